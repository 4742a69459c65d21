//! Which angular bins a direction or a ball falls in (docs/math.md §5.1, §5.3).
//!
//! The answer that defines every map is `⌊(angle − start) / step⌋` of the
//! libm angles: `atan2` for azimuth and elevation, and for a ball of radius
//! `R` at distance `d` the half-widths `β = asin(R/d)` in elevation and
//! `γ = asin(sin β / cos el)` in azimuth. These calls are most of what a
//! lookup costs, so a fast path gets the same angles from `atan` of ratios
//! (`γ = asin(R/ρ)`, ρ the horizontal distance, is the same angle) and keeps
//! its indices only when each lies more than [`ANGLE_SLACK`] from a bin edge.
//! The two paths' angles differ by a few 1e-15 rad where the fast path is
//! used (ratios of at most 0.9, elevations within ±84°), so both floor alike
//! there; anywhere else the exact path answers. Same bins, bit for bit,
//! whichever path runs (tested).

use super::{spherical, Axis, BinBox, LocalGrid};
use crate::geometry::{floor, Vector3};
use std::f64::consts::{FRAC_PI_2, PI};

/// How far (rad) the fast path's angles may lie from libm's before its bin
/// indices are not trusted: ~2000 times the worst difference of the two.
pub(super) const ANGLE_SLACK: f64 = 1e-11;

/// Ratios (`R/ρ`, and `ρ/d` from below) beyond which the fast path defers:
/// near 1 the half-width's error grows without bound.
const RATIO_LIMIT: f64 = 0.9;

impl Axis {
    /// [`Axis::index`] of `v` when `v` lies more than `slack` bins from the
    /// nearest bin edge; `None` near an edge (or for a non-finite `v`).
    #[inline]
    fn index_clear(&self, v: f64, slack: f64) -> Option<isize> {
        let q = (v - self.start) / self.step;
        let i = floor(q);
        let frac = q - i as f64;
        (frac > slack && frac < 1.0 - slack).then_some(i as isize)
    }

    /// Bins `a..=b` (unclamped indices) clipped to the axis; `None` when
    /// disjoint. The flag says whether `a..=b` reaches outside the axis.
    #[inline]
    fn clip(&self, a: isize, b: isize) -> Option<(usize, usize, bool)> {
        if b < 0 || a >= self.count as isize {
            return None;
        }
        let outside = a < 0 || b >= self.count as isize;
        Some((
            a.max(0) as usize,
            b.min(self.count as isize - 1) as usize,
            outside,
        ))
    }
}

/// Bin `(a, e)` (unclamped indices) if it lies on both axes.
#[inline]
pub(super) fn bin_in(
    azimuth: &Axis,
    elevation: &Axis,
    a: isize,
    e: isize,
) -> Option<(usize, usize)> {
    (a >= 0 && e >= 0 && a < azimuth.count as isize && e < elevation.count as isize)
        .then_some((a as usize, e as usize))
}

/// The slack of [`ANGLE_SLACK`] in bins of each axis.
pub(super) fn slack(azimuth: &Axis, elevation: &Axis) -> [f64; 2] {
    [ANGLE_SLACK / azimuth.step, ANGLE_SLACK / elevation.step]
}

/// The unclamped (azimuth, elevation) bin indices of grid-frame direction
/// `v`, as `⌊(atan2 − start)/step⌋` gives them.
#[inline]
pub(super) fn direction_index(
    azimuth: &Axis,
    elevation: &Axis,
    slack: [f64; 2],
    v: &Vector3,
) -> (isize, isize) {
    direction_index_fast(azimuth, elevation, slack, v).unwrap_or_else(|| {
        let (_, az, el) = spherical(v);
        (azimuth.index(az), elevation.index(el))
    })
}

/// [`direction_index`] from `atan` of ratios when both indices are clear of
/// bin edges; `None` (undecided) otherwise.
#[inline]
fn direction_index_fast(
    azimuth: &Axis,
    elevation: &Axis,
    slack: [f64; 2],
    v: &Vector3,
) -> Option<(isize, isize)> {
    // NaN goes on, and index_clear rejects it.
    if v.x <= 0.0 {
        return None;
    }
    // atan(y/x) is atan2(y, x) for x > 0, atan(z/ρ) is atan2(z, ρ).
    let rho = (v.x * v.x + v.y * v.y).sqrt();
    let (az, el) = ((v.y / v.x).atan(), (v.z / rho).atan());
    Some((
        azimuth.index_clear(az, slack[0])?,
        elevation.index_clear(el, slack[1])?,
    ))
}

impl LocalGrid {
    /// The angular bins that may hold any point of the ball of radius
    /// `radius` around scene point `centre` (a superset), with the ball's
    /// range interval. `None` when the ball misses the field of view.
    #[inline]
    pub fn ball_bins(&self, centre: &Vector3, radius: f64) -> Option<BinBox> {
        let c = self.scene_from_grid.transpose() * (centre - self.origin);
        match self.ball_bins_fast(&c, radius) {
            Some(found) => found,
            None => self.ball_bins_exact(&c, radius),
        }
    }

    /// [`LocalGrid::ball_bins`] of the grid-frame offset `c` from libm's
    /// angles: the definition.
    pub(super) fn ball_bins_exact(&self, c: &Vector3, radius: f64) -> Option<BinBox> {
        let (dist, az, el) = spherical(c);
        let (el_lo, el_hi, az_lo, az_hi) = if dist <= radius {
            (-FRAC_PI_2, FRAC_PI_2, -PI, PI)
        } else {
            let beta = (radius / dist).min(1.0).asin();
            let gamma = if el.abs() + beta < FRAC_PI_2 {
                (beta.sin() / el.cos()).min(1.0).asin()
            } else {
                PI
            };
            (el - beta, el + beta, az - gamma, az + gamma)
        };
        let (e0, e1, e_out) = self
            .elevation
            .clip(self.elevation.index(el_lo), self.elevation.index(el_hi))?;
        // The grid's azimuths lie within (−π/2, π/2): no wrap to handle unless
        // the cone covers everything.
        let (a0, a1, a_out) = self
            .azimuth
            .clip(self.azimuth.index(az_lo), self.azimuth.index(az_hi))?;
        Some(BinBox {
            azimuth: (a0, a1),
            elevation: (e0, e1),
            range: ((dist - radius).max(0.0), dist + radius),
            outside: a_out || e_out,
            centre: self.bin_at(self.azimuth.index(az), self.elevation.index(el)),
        })
    }

    /// [`LocalGrid::ball_bins_exact`] from `atan` of ratios, when every index
    /// it needs is clear of bin edges; `None` (undecided) otherwise.
    #[inline]
    pub(super) fn ball_bins_fast(&self, c: &Vector3, radius: f64) -> Option<Option<BinBox>> {
        let rho = (c.x * c.x + c.y * c.y).sqrt();
        let dist = c.norm();
        // R/d ≤ R/ρ: one bound covers both half-widths. NaN defers.
        let (s, g) = (radius / dist, radius / rho);
        if !(c.x > 0.0 && g <= RATIO_LIMIT && rho >= (1.0 - RATIO_LIMIT) * dist) {
            return None;
        }
        let (az, el) = ((c.y / c.x).atan(), (c.z / rho).atan());
        // asin(x) = atan(x / √(1 − x²)).
        let beta = (s / (1.0 - s * s).sqrt()).atan();
        let gamma = (g / (1.0 - g * g).sqrt()).atan();
        let [sa, se] = self.slack;
        let (el_lo, el_hi) = (
            self.elevation.index_clear(el - beta, se)?,
            self.elevation.index_clear(el + beta, se)?,
        );
        let (az_lo, az_hi) = (
            self.azimuth.index_clear(az - gamma, sa)?,
            self.azimuth.index_clear(az + gamma, sa)?,
        );
        let centre = (
            self.azimuth.index_clear(az, sa)?,
            self.elevation.index_clear(el, se)?,
        );
        let Some((e0, e1, e_out)) = self.elevation.clip(el_lo, el_hi) else {
            return Some(None);
        };
        let Some((a0, a1, a_out)) = self.azimuth.clip(az_lo, az_hi) else {
            return Some(None);
        };
        Some(Some(BinBox {
            azimuth: (a0, a1),
            elevation: (e0, e1),
            range: ((dist - radius).max(0.0), dist + radius),
            outside: a_out || e_out,
            centre: self.bin_at(centre.0, centre.1),
        }))
    }

    /// The angular bin holding scene point `p`, if any.
    #[inline]
    pub fn bin_of(&self, p: &Vector3) -> Option<(usize, usize)> {
        let v = self.scene_from_grid.transpose() * (p - self.origin);
        let (a, e) = direction_index(&self.azimuth, &self.elevation, self.slack, &v);
        self.bin_at(a, e)
    }

    /// Bin `(a, e)` (unclamped indices) if it is in the grid.
    #[inline]
    fn bin_at(&self, a: isize, e: isize) -> Option<(usize, usize)> {
        bin_in(&self.azimuth, &self.elevation, a, e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Matrix3;
    use rand::{Rng, SeedableRng};

    /// An empty grid with the bench scanner's kind of bins (0.2°) over a
    /// wide field of view.
    fn grid() -> LocalGrid {
        grid_of(700, 500)
    }

    /// An empty grid of `azimuths` × `elevations` bins of 0.2°, centred.
    fn grid_of(azimuths: usize, elevations: usize) -> LocalGrid {
        let step = 0.2f64.to_radians();
        let axis = |count: usize| Axis {
            start: -(count as f64) * step / 2.0,
            step,
            count,
        };
        LocalGrid::new(
            Vector3::zeros(),
            Matrix3::identity(),
            axis(azimuths),
            axis(elevations),
            3.0,
            &[],
            &Matrix3::zeros(),
        )
    }

    /// Unit direction at azimuth `az`, elevation `el` (grid frame).
    fn direction(az: f64, el: f64) -> Vector3 {
        Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
    }

    /// An angle on a bin edge of `axis`, nudged by up to a few 1e-15 rad
    /// (where `atan` and `atan2` may floor apart), or anywhere.
    fn angle(rng: &mut impl Rng, axis: &Axis, on_edge: bool) -> f64 {
        if on_edge {
            let k = rng.random_range(0..=axis.count) as f64;
            axis.start + k * axis.step + rng.random_range(-4.0..4.0) * f64::EPSILON
        } else {
            rng.random_range(-1.7..1.7)
        }
    }

    /// The fast path answers nearly every input off the bin edges (else it
    /// would be exact and useless).
    fn assert_decides_nearly_all(decided: usize, random: usize) {
        assert!(
            decided as f64 > 0.999 * random as f64,
            "{decided} of {random}"
        );
    }

    #[test]
    fn direction_bins_are_atan2_s_bit_for_bit() {
        let grid = grid();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let (mut decided, mut random) = (0, 0);
        for i in 0..400_000 {
            let on_edge = i % 2 == 0;
            let both = on_edge && rng.random_bool(0.5);
            let az = angle(&mut rng, &grid.azimuth, on_edge);
            let el = angle(&mut rng, &grid.elevation, both);
            let v = direction(az, el) * rng.random_range(0.01..10.0);
            let (_, az, el) = spherical(&v);
            let exact = (grid.azimuth.index(az), grid.elevation.index(el));
            let fast = direction_index_fast(&grid.azimuth, &grid.elevation, grid.slack, &v);
            if let Some(fast) = fast {
                assert_eq!(fast, exact, "{v:?}");
            }
            assert_eq!(
                direction_index(&grid.azimuth, &grid.elevation, grid.slack, &v),
                exact
            );
            if !on_edge && v.x > 0.0 {
                random += 1;
                decided += usize::from(fast.is_some());
            }
        }
        assert_decides_nearly_all(decided, random);
    }

    #[test]
    fn ball_bins_are_the_exact_ones_bit_for_bit() {
        let grid = grid();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let (mut decided, mut random) = (0, 0);
        for i in 0..400_000 {
            let on_edge = i % 2 == 0;
            let (az, el) = (
                angle(&mut rng, &grid.azimuth, false),
                angle(&mut rng, &grid.elevation, false).clamp(-1.5, 1.5),
            );
            let dist = rng.random_range(0.05..5.0);
            let c = direction(az, el) * dist;
            let (c, radius) = if i % 4 == 1 {
                // Nearly tangent to the vertical through the origin (R/ρ → 1,
                // where asin is ill-conditioned), with az + γ on an edge.
                let g = 1.0 - 10f64.powf(-rng.random_range(6.0..15.0));
                let edge = angle(&mut rng, &grid.azimuth, true);
                let az = edge - g.asin();
                let rho = dist * el.cos();
                (direction(az, el) * dist, g * rho)
            } else if on_edge {
                // el − β or el + β on an edge: R = d sin|el − edge|.
                let edge = angle(&mut rng, &grid.elevation, true);
                (c, dist * (el - edge).abs().min(1.5).sin())
            } else {
                (c, dist * rng.random_range(0.0..1.2f64).powi(3))
            };
            let exact = grid.ball_bins_exact(&c, radius);
            let fast = grid.ball_bins_fast(&c, radius);
            if let Some(fast) = fast {
                assert_eq!(fast, exact, "{c:?} {radius}");
            }
            let rho = (c.x * c.x + c.y * c.y).sqrt();
            if i % 4 == 3 && c.x > 0.0 && radius < 0.5 * rho && rho > 0.2 * dist {
                random += 1;
                decided += usize::from(fast.is_some());
            }
        }
        assert_decides_nearly_all(decided, random);
    }

    #[test]
    fn ball_bins_near_the_pole_are_the_exact_ones() {
        // Elevations up to ±90°: near the pole cos(el) loses its relative
        // precision, and so does the exact path's γ = asin(sin β / cos el).
        let grid = grid_of(700, 900);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
        for _ in 0..200_000 {
            // Built from ρ and z, not from an angle: an elevation that is a
            // double would hide the rounding of atan2.
            let z = rng.random_range(0.05..5.0f64) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let rho = z.abs() * 10f64.powf(-rng.random_range(2.0..9.0));
            let g = rng.random_range(0.0..RATIO_LIMIT);
            // az + γ near an edge, by more than the slack but less than the
            // exact path's own error there.
            let edge = angle(&mut rng, &grid.azimuth, true) + rng.random_range(-1e-6..1e-6);
            let az = edge - g.asin();
            let c = Vector3::new(rho * az.cos(), rho * az.sin(), z);
            let radius = g * (c.x * c.x + c.y * c.y).sqrt();
            if let Some(fast) = grid.ball_bins_fast(&c, radius) {
                assert_eq!(fast, grid.ball_bins_exact(&c, radius), "{c:?} {radius}");
            }
        }
    }
}
