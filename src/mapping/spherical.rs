//! The local spherical grid of one viewpoint (MATH.md §5.1): range x azimuth x
//! elevation bins around the mean sensor origin holding the log-odds of the
//! extended OPDF of that viewpoint's beams.
//!
//! [DESIGN] The grid's axes follow the nominal sensor, not the scene: grid x is
//! the boresight (camera z), y the camera x, z the camera y. A beam at
//! horizontal angle h and vertical angle v then has azimuth h and elevation v,
//! the raster maps onto the angular bins one to one, and no viewpoint puts its
//! field of view across the poles or the azimuth wrap (MATH.md §8, open
//! question 3, leaves the choice open). Merging costs one extra rotation.

use super::opdf::{logit, OpdfParams};
use crate::geometry::{Matrix3, Vector3};

/// A bin axis: `count` bins of `step` from `start`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Axis {
    /// Lower edge of bin 0.
    pub start: f64,
    /// Bin width.
    pub step: f64,
    /// Number of bins.
    pub count: usize,
}

impl Axis {
    /// The (unclamped) bin index of `v`.
    #[inline]
    fn index(&self, v: f64) -> isize {
        ((v - self.start) / self.step).floor() as isize
    }

    /// Centre of bin `i`.
    #[inline]
    pub fn centre(&self, i: usize) -> f64 {
        self.start + (i as f64 + 0.5) * self.step
    }

    /// Upper edge of the last bin.
    pub fn end(&self) -> f64 {
        self.start + self.step * self.count as f64
    }

    /// Bins overlapping `[lo, hi]`, clipped; `None` when disjoint. The flag says
    /// whether `[lo, hi]` reaches outside the axis.
    fn span(&self, lo: f64, hi: f64) -> Option<(usize, usize, bool)> {
        let (a, b) = (self.index(lo), self.index(hi));
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

/// One level of the min / max / sum / count pyramid over the bins.
#[derive(Clone, Debug)]
struct Level {
    dims: [usize; 3],
    min: Vec<f32>,
    max: Vec<f32>,
    sum: Vec<f32>,
    known: Vec<u32>,
}

/// Aggregate of the bins of a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxSummary {
    /// Smallest log-odds (unknown bins count as 0).
    pub min: f32,
    /// Largest log-odds.
    pub max: f32,
    /// Mean log-odds.
    pub mean: f32,
    /// Bins some beam filled.
    pub known: u32,
}

/// A filled local grid.
#[derive(Clone, Debug)]
pub struct LocalGrid {
    /// Mean sensor origin û in the scene frame.
    pub origin: Vector3,
    /// Rotation taking grid coordinates to scene coordinates.
    pub scene_from_grid: Matrix3,
    /// Range bins (m).
    pub range: Axis,
    /// Azimuth bins (rad).
    pub azimuth: Axis,
    /// Elevation bins (rad).
    pub elevation: Axis,
    /// `[range, azimuth, elevation]` bin counts.
    dims: [usize; 3],
    /// Log-odds per bin, range innermost (0: unknown).
    values: Vec<f32>,
    /// Whether some beam filled each angular bin (all its range bins).
    filled: Vec<bool>,
    /// The pyramid above the bins: level k aggregates 2^k bins a side.
    levels: Vec<Level>,
}

/// A beam's end as the modeller knows it, in the scene frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BeamEnd {
    /// A measured point with its propagated covariance.
    Hit { point: Vector3, covariance: Matrix3 },
    /// No return: the beam's unit direction; free space up to the maximum range.
    Miss { direction: Vector3 },
}

/// `(r, azimuth, elevation)` of a grid-frame vector.
#[inline]
pub fn spherical(v: &Vector3) -> (f64, f64, f64) {
    let r = v.norm();
    (r, v.y.atan2(v.x), v.z.atan2((v.x * v.x + v.y * v.y).sqrt()))
}

impl LocalGrid {
    /// An empty grid (every bin unknown).
    pub fn new(
        origin: Vector3,
        scene_from_grid: Matrix3,
        range: Axis,
        azimuth: Axis,
        elevation: Axis,
    ) -> Self {
        let dims = [range.count, azimuth.count, elevation.count];
        Self {
            origin,
            scene_from_grid,
            range,
            azimuth,
            elevation,
            dims,
            values: vec![0.0; dims.iter().product()],
            filled: vec![false; dims[1] * dims[2]],
            levels: Vec::new(),
        }
    }

    #[inline]
    fn flat(dims: &[usize; 3], r: usize, a: usize, e: usize) -> usize {
        (a * dims[2] + e) * dims[0] + r
    }

    /// Fills the grid from one viewpoint's beams: for each beam, every range
    /// bin of its angular bin gets `logit(clamp(p_ext(λ)))`, with
    /// `σ² = vᵀ Γ_s v` and `σ_o² = vᵀ Γ_u v` (MATH.md §4.5); beams sharing an
    /// angular bin are averaged. `origin_covariance` is Γ_u (scene frame).
    pub fn fill(
        &mut self,
        beams: &[BeamEnd],
        origin_covariance: &Matrix3,
        params: &OpdfParams,
        max_range: f64,
    ) {
        let dims = self.dims;
        let grid_from_scene = self.scene_from_grid.transpose();
        let free = logit(params.p_lo) as f32;
        let mut column = vec![0f32; dims[0]];
        let mut hits_in_bin = vec![0u32; dims[1] * dims[2]];
        for beam in beams {
            let (direction, range, sigma) = match beam {
                BeamEnd::Hit { point, covariance } => {
                    let d = point - self.origin;
                    let r = d.norm();
                    let v = d / r;
                    // [DESIGN] Bins sample the profile at their centres, Δρ apart:
                    // the sampled profile is the profile seen through a bin, whose
                    // position error is uniform over Δρ (variance Δρ²/12). Without
                    // it a surface between two centres, σ ≪ Δρ, raises neither.
                    let sigma2 = (v.transpose() * covariance * v)[0].max(0.0)
                        + self.range.step.powi(2) / 12.0;
                    (v, r, sigma2.sqrt())
                }
                BeamEnd::Miss { direction } => (*direction, f64::INFINITY, 0.0),
            };
            let sigma_o = (direction.transpose() * origin_covariance * direction)[0]
                .max(0.0)
                .sqrt();
            let (_, az, el) = spherical(&(grid_from_scene * direction));
            let (a, e) = (self.azimuth.index(az), self.elevation.index(el));
            if a < 0 || e < 0 || a >= dims[1] as isize || e >= dims[2] as isize {
                continue;
            }
            let (a, e) = (a as usize, e as usize);
            // Exact values only near the origin step and the surface; the
            // clamped free value everywhere between.
            let near_origin = 8.0 * sigma_o;
            let reach = if range.is_finite() {
                range + 8.0 * sigma.max(params.thickness)
            } else {
                max_range
            };
            for (i, out) in column.iter_mut().enumerate() {
                let lambda = self.range.centre(i);
                *out = if lambda > reach {
                    0.0
                } else if lambda > near_origin
                    && (!range.is_finite() || lambda < range - 8.0 * sigma.max(params.thickness))
                {
                    free
                } else {
                    logit(params.stored(lambda, range, sigma, sigma_o)) as f32
                };
            }
            let slot = a * dims[2] + e;
            let n = hits_in_bin[slot];
            hits_in_bin[slot] += 1;
            self.filled[slot] = true;
            let bins = &mut self.values[slot * dims[0]..(slot + 1) * dims[0]];
            if n == 0 {
                bins.copy_from_slice(&column);
            } else {
                // Running mean of the beams in this bin.
                let w = 1.0 / (n + 1) as f32;
                for (old, v) in bins.iter_mut().zip(&column) {
                    *old += (v - *old) * w;
                }
            }
        }
        self.build_pyramid();
    }

    fn build_pyramid(&mut self) {
        self.levels.clear();
        let mut dims = self.dims;
        while dims.iter().any(|&d| d > 1) {
            let prev_dims = dims;
            dims = dims.map(|d| d.div_ceil(2));
            let n = dims.iter().product();
            let mut next = Level {
                dims,
                min: vec![f32::INFINITY; n],
                max: vec![f32::NEG_INFINITY; n],
                sum: vec![0.0; n],
                known: vec![0; n],
            };
            for a in 0..prev_dims[1] {
                for e in 0..prev_dims[2] {
                    for r in 0..prev_dims[0] {
                        let i = Self::flat(&prev_dims, r, a, e);
                        let j = Self::flat(&dims, r / 2, a / 2, e / 2);
                        let (min, max, sum, known) = match self.levels.last() {
                            None => {
                                let v = self.values[i];
                                (v, v, v, self.filled[i / prev_dims[0]] as u32)
                            }
                            Some(prev) => (prev.min[i], prev.max[i], prev.sum[i], prev.known[i]),
                        };
                        next.min[j] = next.min[j].min(min);
                        next.max[j] = next.max[j].max(max);
                        next.sum[j] += sum;
                        next.known[j] += known;
                    }
                }
            }
            self.levels.push(next);
        }
    }

    /// Min, max, mean and known count over a superset of the bins
    /// `[r0..=r1] x [a0..=a1] x [e0..=e1]`: the coarsest pyramid level where
    /// the box spans at most two cells per axis (conservative for min/max).
    pub fn query(&self, r: (usize, usize), a: (usize, usize), e: (usize, usize)) -> BoxSummary {
        let span = (r.1 - r.0).max(a.1 - a.0).max(e.1 - e.0) + 1;
        let mut level = 0;
        while level < self.levels.len() && (span >> level) > 2 {
            level += 1;
        }
        let (mut min, mut max, mut sum, mut known, mut bins) =
            (f32::INFINITY, f32::NEG_INFINITY, 0.0f32, 0u32, 0usize);
        let dims = if level == 0 {
            self.dims
        } else {
            self.levels[level - 1].dims
        };
        for aa in a.0 >> level..=a.1 >> level {
            for ee in e.0 >> level..=e.1 >> level {
                for rr in r.0 >> level..=r.1 >> level {
                    let i = Self::flat(&dims, rr, aa, ee);
                    let (lo, hi, s, k) = if level == 0 {
                        let v = self.values[i];
                        (v, v, v, self.filled[i / dims[0]] as u32)
                    } else {
                        let l = &self.levels[level - 1];
                        (l.min[i], l.max[i], l.sum[i], l.known[i])
                    };
                    min = min.min(lo);
                    max = max.max(hi);
                    sum += s;
                    known += k;
                    bins += 1 << (3 * level);
                }
            }
        }
        BoxSummary {
            min,
            max,
            mean: sum / bins as f32,
            known,
        }
    }

    /// The log-odds of the bin containing scene point `p` (0 outside the grid).
    pub fn value_at(&self, p: &Vector3) -> f32 {
        let (r, az, el) = spherical(&(self.scene_from_grid.transpose() * (p - self.origin)));
        let (i, a, e) = (
            self.range.index(r),
            self.azimuth.index(az),
            self.elevation.index(el),
        );
        let dims = self.dims;
        if i < 0
            || a < 0
            || e < 0
            || i >= dims[0] as isize
            || a >= dims[1] as isize
            || e >= dims[2] as isize
        {
            return 0.0;
        }
        self.values[Self::flat(&dims, i as usize, a as usize, e as usize)]
    }

    /// The bins that may hold any point of the ball of radius `radius` around
    /// scene point `centre` (a superset), and whether the ball reaches outside
    /// the grid. `None` when it misses the grid.
    pub fn ball_bins(&self, centre: &Vector3, radius: f64) -> Option<([(usize, usize); 3], bool)> {
        let c = self.scene_from_grid.transpose() * (centre - self.origin);
        let (dist, az, el) = spherical(&c);
        let (r0, r1, r_out) = self.range.span((dist - radius).max(0.0), dist + radius)?;
        let half_pi = std::f64::consts::FRAC_PI_2;
        let (el_lo, el_hi, az_lo, az_hi) = if dist <= radius {
            (
                -half_pi,
                half_pi,
                -std::f64::consts::PI,
                std::f64::consts::PI,
            )
        } else {
            let beta = (radius / dist).min(1.0).asin();
            let gamma = if el.abs() + beta < half_pi {
                (beta.sin() / el.cos()).min(1.0).asin()
            } else {
                std::f64::consts::PI
            };
            (el - beta, el + beta, az - gamma, az + gamma)
        };
        let (e0, e1, e_out) = self.elevation.span(el_lo, el_hi)?;
        // The grid's azimuths lie within (−π/2, π/2): no wrap to handle unless
        // the cone covers everything.
        let (a0, a1, a_out) = self.azimuth.span(az_lo, az_hi)?;
        Some(([(r0, r1), (a0, a1), (e0, e1)], r_out || e_out || a_out))
    }
}

#[cfg(test)]
mod tests;
