//! Which angular bins a direction or a ball falls in (docs/math.md §5.1, §5.3).
//!
//! The answer that defines every map is `⌊(angle − start) / step⌋` of the
//! libm angles: `atan2` for azimuth and elevation, and for a ball of radius
//! `R` at distance `d` the half-widths `β = asin(R/d)` in elevation and
//! `γ = asin(sin β / cos el)` in azimuth. These calls are most of what a
//! lookup costs, so two fast paths answer first, each only where its indices
//! lie more than [`ANGLE_SLACK`] from a bin edge:
//! - the tangent path ([`super::tangent`]) compares the angles' tangents
//!   (ratios of coordinates, and the addition formula for `el ± β`, `az ± γ`)
//!   with tabulated tangents of the bin edges, and computes no angle;
//! - the `atan` path gets the angles from `atan` of ratios (`γ = asin(R/ρ)`,
//!   ρ the horizontal distance, is the same angle), for axes the tangent path
//!   has no table for and the few lookups it leaves undecided.
//!
//! Both paths' angles differ from libm's by at most ~1e-14 rad where they are
//! used (ratios of at most 0.9, elevations within ±84°, sums away from ±π/2),
//! so they floor alike; anywhere else the exact path answers. Same bins, bit
//! for bit, whichever path runs (tested).

use super::tangent::{tan_sum, TangentBins};
use super::{spherical, Axis, BinBox, LocalGrid};
use crate::geometry::{floor, Vector3};
use std::f64::consts::{FRAC_PI_2, PI};

/// How far (rad) the fast path's angles may lie from libm's before its bin
/// indices are not trusted: ~2000 times the worst difference of the two.
pub(super) const ANGLE_SLACK: f64 = 1e-11;

/// Ratios (`R/ρ`, and `ρ/d` from below) beyond which the fast path defers:
/// near 1 the half-width's error grows without bound.
const RATIO_LIMIT: f64 = 0.9;

/// The bounding cone of a ball, as the fast paths need it: the horizontal
/// and full distances of its centre, and the tangents of its half-widths
/// `β = asin(R/d)` in elevation and `γ = asin(R/ρ)` in azimuth
/// (`tan asin x = x/√(1 − x²)`).
struct Cone {
    rho: f64,
    dist: f64,
    tan_beta: f64,
    tan_gamma: f64,
}

/// The [`Cone`] of the ball of `radius` around the grid-frame offset `c`
/// when the fast paths may answer for it: ahead of the origin (x > 0), with
/// `R/ρ ≤` [`RATIO_LIMIT`] and `ρ/d` at least `1 −` [`RATIO_LIMIT`]
/// (`R/d ≤ R/ρ`: one bound covers both half-widths). NaN defers.
#[inline]
fn ball_cone(c: &Vector3, radius: f64) -> Option<Cone> {
    let rho = (c.x * c.x + c.y * c.y).sqrt();
    let dist = c.norm();
    let (s, g) = (radius / dist, radius / rho);
    (c.x > 0.0 && g <= RATIO_LIMIT && rho >= (1.0 - RATIO_LIMIT) * dist).then(|| Cone {
        rho,
        dist,
        tan_beta: s / (1.0 - s * s).sqrt(),
        tan_gamma: g / (1.0 - g * g).sqrt(),
    })
}

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

/// The bin `(azimuth, elevation)` of grid-frame direction `v`, if it lies
/// in the grid: the bin of `⌊(atan2 − start)/step⌋` on each axis.
#[inline]
pub(super) fn direction_bin(
    [azimuth, elevation]: [&Axis; 2],
    slack: [f64; 2],
    tangents: &[TangentBins; 2],
    v: &Vector3,
) -> Option<(usize, usize)> {
    let (a, e) = direction_index_tangent(tangents, v)
        .unwrap_or_else(|| direction_index_off_table([azimuth, elevation], slack, v));
    bin_in(azimuth, elevation, a, e)
}

/// [`direction_bin`]'s indices where the tangent table leaves them undecided
/// (under 0.1% of directions): the `atan` path, then libm. Kept out of line
/// so that the table's path inlines into its callers.
#[cold]
#[inline(never)]
fn direction_index_off_table(
    [azimuth, elevation]: [&Axis; 2],
    slack: [f64; 2],
    v: &Vector3,
) -> (isize, isize) {
    direction_index_fast(azimuth, elevation, slack, v).unwrap_or_else(|| {
        let (_, az, el) = spherical(v);
        (azimuth.index(az), elevation.index(el))
    })
}

/// The (azimuth, elevation) bin indices of `v` from the tangents `y/x` and
/// `z/ρ` ([`TangentBins::locate`]: −1 and `count` stand for any index off
/// the axis); `None` (undecided) near a bin edge.
#[inline]
fn direction_index_tangent(tangents: &[TangentBins; 2], v: &Vector3) -> Option<(isize, isize)> {
    if v.x.is_nan() || v.x <= 0.0 {
        return None;
    }
    let rho = (v.x * v.x + v.y * v.y).sqrt();
    Some((
        tangents[0].locate(v.y / v.x)?,
        tangents[1].locate(v.z / rho)?,
    ))
}

/// The unclamped bin indices of `v` from `atan` of ratios when both are
/// clear of bin edges; `None` (undecided) otherwise.
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
        let c = self.grid_offset(centre);
        let fast = self
            .ball_bins_tangent(&c, radius)
            .or_else(|| self.ball_bins_fast(&c, radius));
        match fast {
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
        // The grid's azimuths lie within (−π/2, π/2): no wrap to handle unless
        // the cone covers everything.
        let (azimuth, elevation) = (&self.azimuth, &self.elevation);
        self.bin_box(
            (elevation.index(el_lo), elevation.index(el_hi)),
            (azimuth.index(az_lo), azimuth.index(az_hi)),
            (azimuth.index(az), elevation.index(el)),
            (dist, radius),
        )
    }

    /// [`LocalGrid::ball_bins_exact`] from tangents alone, when every index
    /// it needs is decided ([`TangentBins::locate`]); `None` otherwise.
    #[inline]
    pub(super) fn ball_bins_tangent(&self, c: &Vector3, radius: f64) -> Option<Option<BinBox>> {
        let cone = ball_cone(c, radius)?;
        let (tb, tg) = (cone.tan_beta, cone.tan_gamma);
        let (ta, te) = (c.y / c.x, c.z / cone.rho);
        let [azimuth, elevation] = &self.tangents;
        Some(self.bin_box(
            (
                elevation.locate(tan_sum(te, -tb))?,
                elevation.locate(tan_sum(te, tb))?,
            ),
            (
                azimuth.locate(tan_sum(ta, -tg))?,
                azimuth.locate(tan_sum(ta, tg))?,
            ),
            (azimuth.locate(ta)?, elevation.locate(te)?),
            (cone.dist, radius),
        ))
    }

    /// [`LocalGrid::ball_bins_exact`] from `atan` of ratios, when every index
    /// it needs is clear of bin edges; `None` (undecided) otherwise.
    #[inline]
    pub(super) fn ball_bins_fast(&self, c: &Vector3, radius: f64) -> Option<Option<BinBox>> {
        let cone = ball_cone(c, radius)?;
        let (az, el) = ((c.y / c.x).atan(), (c.z / cone.rho).atan());
        let (beta, gamma) = (cone.tan_beta.atan(), cone.tan_gamma.atan());
        let [sa, se] = self.slack;
        Some(self.bin_box(
            (
                self.elevation.index_clear(el - beta, se)?,
                self.elevation.index_clear(el + beta, se)?,
            ),
            (
                self.azimuth.index_clear(az - gamma, sa)?,
                self.azimuth.index_clear(az + gamma, sa)?,
            ),
            (
                self.azimuth.index_clear(az, sa)?,
                self.elevation.index_clear(el, se)?,
            ),
            (cone.dist, radius),
        ))
    }

    /// The ball's bins from the (unclamped) indices of its elevation and
    /// azimuth extents and of its centre.
    #[inline]
    fn bin_box(
        &self,
        (el_lo, el_hi): (isize, isize),
        (az_lo, az_hi): (isize, isize),
        centre: (isize, isize),
        (dist, radius): (f64, f64),
    ) -> Option<BinBox> {
        let (e0, e1, e_out) = self.elevation.clip(el_lo, el_hi)?;
        let (a0, a1, a_out) = self.azimuth.clip(az_lo, az_hi)?;
        Some(BinBox {
            azimuth: (a0, a1),
            elevation: (e0, e1),
            range: ((dist - radius).max(0.0), dist + radius),
            outside: a_out || e_out,
            centre: self.bin_at(centre.0, centre.1),
        })
    }

    /// Scene point `p` in the grid's frame, from its origin: what its bin and
    /// range are read from.
    #[inline]
    pub fn grid_offset(&self, p: &Vector3) -> Vector3 {
        self.scene_from_grid.transpose() * (p - self.origin)
    }

    /// The angular bin holding scene point `p`, if any.
    #[inline]
    pub fn bin_of(&self, p: &Vector3) -> Option<(usize, usize)> {
        let v = self.grid_offset(p);
        direction_bin(
            [&self.azimuth, &self.elevation],
            self.slack,
            &self.tangents,
            &v,
        )
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
        let (mut decided, mut decided_tangent, mut random) = (0, 0, 0);
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
            // The tangent path's −1 / count stand for any index off the axis.
            let tangent = direction_index_tangent(&grid.tangents, &v);
            if let Some((a, e)) = tangent {
                assert_eq!(grid.bin_at(a, e), grid.bin_at(exact.0, exact.1), "{v:?}");
                for (got, want, count) in [
                    (a, exact.0, grid.azimuth.count),
                    (e, exact.1, grid.elevation.count),
                ] {
                    let off = |i: isize| (i < 0, i >= count as isize);
                    assert_eq!(off(got), off(want), "{v:?}");
                    if off(want) == (false, false) {
                        assert_eq!(got, want, "{v:?}");
                    }
                }
            }
            assert_eq!(
                direction_bin(
                    [&grid.azimuth, &grid.elevation],
                    grid.slack,
                    &grid.tangents,
                    &v
                ),
                grid.bin_at(exact.0, exact.1)
            );
            if !on_edge && v.x > 0.0 {
                random += 1;
                decided += usize::from(fast.is_some());
                decided_tangent += usize::from(tangent.is_some());
            }
        }
        assert_decides_nearly_all(decided, random);
        assert_decides_nearly_all(decided_tangent, random);
    }

    #[test]
    fn ball_bins_are_the_exact_ones_bit_for_bit() {
        let grid = grid();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let (mut decided, mut decided_tangent, mut random) = (0, 0, 0);
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
            let tangent = grid.ball_bins_tangent(&c, radius);
            if let Some(tangent) = tangent {
                assert_eq!(tangent, exact, "{c:?} {radius}");
            }
            assert_eq!(grid.ball_bins(&c, radius), exact);
            let rho = (c.x * c.x + c.y * c.y).sqrt();
            if i % 4 == 3 && c.x > 0.0 && radius < 0.5 * rho && rho > 0.2 * dist {
                random += 1;
                decided += usize::from(fast.is_some());
                decided_tangent += usize::from(tangent.is_some());
            }
        }
        assert_decides_nearly_all(decided, random);
        assert_decides_nearly_all(decided_tangent, random);
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
            if let Some(tangent) = grid.ball_bins_tangent(&c, radius) {
                assert_eq!(tangent, grid.ball_bins_exact(&c, radius), "{c:?} {radius}");
            }
        }
    }
}
