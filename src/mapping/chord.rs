//! The cell-occupancy model (docs/math.md §5.4): what one viewpoint says about
//! one octree cell.
//!
//! A beam from the mean origin along the unit direction `v` crosses cell C over
//! the range interval `[a, b]` (the chord). The surface it measured lies at
//! `λ ~ N(r, σ²)` along the beam (`σ² = vᵀ Γ_s v`, §4.5). By the first-hit model
//! of §4.7 the surface is inside C, or in front of it (C occluded), or beyond
//! it (the beam crossed C): [`CellModel::split`].
//!
//! A viewpoint's verdict on C combines the chance `H` that a surface lies
//! inside C (the most confident beam) with the share `F` of C's volume it
//! sees in front of the surface ([`CellModel::free_at`]):
//!
//! `P(C occ) = H + (1 − H) (1 − F) / (2 − F)`
//!
//! — a beam that crossed only part of C says nothing about the rest
//! ([`CellModel::view_occupancy`]). With a risk level ε a viewpoint calls C
//! free only when it sees at least `1 − ε` of it in front of the surface, each
//! point with probability at least `1 − ε`; otherwise it is silent.
//!
//! [`CellModel::occupancy`] is the single-beam chord posterior
//! `P(a ≤ λ ≤ b) + ½ P(λ < a) + p_lo P(λ > b)`: the verdict of one beam whose
//! footprint covers all of C, the building block the tests check against a
//! Monte Carlo of the first-hit model.

use super::opdf::{logit, normal_cdf};
use crate::geometry::Vector3;

/// Standard deviations beyond which a Gaussian tail is taken as 0
/// (Φ(−7) ≈ 1.3e-12): it bounds the band around a surface where the chord
/// probability is evaluated, and the origin step.
pub const TAIL: f64 = 7.0;

/// The constants of the cell-occupancy model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellModel {
    /// Probability a crossed (free) cell gets; also the lower clamp (0.02).
    pub p_lo: f64,
    /// Upper clamp of a beam's probability (0.98), so log-odds stay finite.
    pub p_hi: f64,
    /// Risk level ε: a viewpoint calls a cell free only when it sees at least
    /// `1 − ε` of it in front of the surface, each point with `P(λ > ρ) ≥ 1 − ε`.
    /// `None`: off (every part seen free counts as free evidence).
    pub risk: Option<f64>,
}

impl Default for CellModel {
    fn default() -> Self {
        Self {
            p_lo: 0.02,
            p_hi: 0.98,
            risk: None,
        }
    }
}

/// A beam as the cell model sees it, in the scene frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beam {
    /// Unit direction from the mean origin.
    pub direction: Vector3,
    /// Measured range r (m); `f64::INFINITY` for a no-return beam.
    pub range: f64,
    /// Range standard deviation along the beam, `√(vᵀ Γ_s v)`.
    pub sigma: f64,
    /// Origin standard deviation along the beam, `√(vᵀ Γ_u v)`.
    pub sigma_origin: f64,
}

/// Where a beam's surface lies along its line, `λ ~ N(range, σ²)`, and the
/// origin's σ_o along it: a [`Beam`] without its direction, as a bin's
/// nearest surface keeps it (§5.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Range r (m); `f64::INFINITY` for a no-return beam.
    pub range: f64,
    /// Range standard deviation σ.
    pub sigma: f64,
    /// Origin standard deviation σ_o.
    pub sigma_origin: f64,
}

impl Surface {
    /// [`Beam::band_start`] of this surface.
    #[inline]
    pub fn band_start(&self, max_range: f64) -> f64 {
        if self.range.is_finite() {
            self.range - TAIL * self.sigma
        } else {
            max_range
        }
    }
}

impl Beam {
    /// The beam's surface (its range, σ and σ_o).
    #[inline]
    pub fn surface(&self) -> Surface {
        Surface {
            range: self.range,
            sigma: self.sigma,
            sigma_origin: self.sigma_origin,
        }
    }

    /// Where this beam stops carrying information: `r + TAIL σ`, or the
    /// maximum range for a no-return beam.
    #[inline]
    pub fn reach(&self, max_range: f64) -> f64 {
        if self.range.is_finite() {
            self.range + TAIL * self.sigma
        } else {
            max_range
        }
    }

    /// Where the surface band starts: before it the beam says "free" (`p_lo`)
    /// to within Φ(−TAIL).
    #[inline]
    pub fn band_start(&self, max_range: f64) -> f64 {
        self.surface().band_start(max_range)
    }
}

impl CellModel {
    /// The model with risk level `risk` (None: off).
    pub fn with_risk(risk: Option<f64>) -> Self {
        Self {
            risk,
            ..Self::default()
        }
    }

    /// Log-odds of a cell every crossing beam certifies free.
    pub fn free_log_odds(&self) -> f32 {
        logit(self.p_lo) as f32
    }

    /// `P(C occ | beam)` for the chord `[a, b]` (`0 ≤ a ≤ b`), clamped to
    /// `[p_lo, p_hi]`; `None` when the beam says nothing about C (C lies
    /// wholly behind its surface band, or beyond the maximum range).
    pub fn occupancy(&self, beam: &Beam, a: f64, b: f64, max_range: f64) -> Option<f64> {
        if a > beam.reach(max_range) || (!beam.range.is_finite() && a >= max_range) {
            return None;
        }
        let (before, inside, after) = self.split(beam, a, b, max_range);
        let q = match self.risk {
            Some(eps) if after < 1.0 - eps => 0.5,
            _ => self.p_lo,
        };
        let chord = inside + 0.5 * before + q * after;
        let w = origin_step(0.5 * (a + b), beam.sigma_origin);
        Some(((1.0 - w) * 0.5 + w * chord).clamp(self.p_lo, self.p_hi))
    }

    /// Where the surface lies against the chord `[a, b]`:
    /// `(P(λ < a), P(a ≤ λ ≤ b), P(λ > b))`. A no-return beam is beyond every
    /// chord that starts within the maximum range, and says nothing past it.
    pub fn split(&self, beam: &Beam, a: f64, b: f64, max_range: f64) -> (f64, f64, f64) {
        if !beam.range.is_finite() {
            return (0.0, 0.0, f64::from(a < max_range));
        }
        let (r, sigma) = (beam.range, beam.sigma);
        if sigma <= 0.0 {
            return (
                f64::from(r < a),
                f64::from(a <= r && r <= b),
                f64::from(r > b),
            );
        }
        if a > r + TAIL * sigma {
            return (1.0, 0.0, 0.0);
        }
        if b < r - TAIL * sigma {
            return (0.0, 0.0, 1.0);
        }
        let before = normal_cdf((a - r) / sigma);
        let after = normal_cdf((r - b) / sigma);
        (before, (1.0 - before - after).max(0.0), after)
    }

    /// `P(λ > ρ)` for a beam with a return: [`CellModel::split`]'s last term
    /// at the chord `[ρ, ρ]`, with one tail evaluated instead of two.
    fn beyond(surface: &Surface, rho: f64) -> f64 {
        let (r, sigma) = (surface.range, surface.sigma);
        if sigma <= 0.0 {
            f64::from(r > rho)
        } else if rho > r + TAIL * sigma {
            0.0
        } else if rho < r - TAIL * sigma {
            1.0
        } else {
            normal_cdf((r - rho) / sigma)
        }
    }

    /// How surely the point at range `rho` on this beam is free: `P(λ > ρ)`
    /// times the origin step `Φ(ρ / σ_o)`, or 0 when the risk level does not
    /// allow calling it free (`P(λ > ρ) < 1 − ε`). A no-return beam frees every
    /// point within the maximum range.
    pub fn free_at(&self, surface: &Surface, rho: f64, max_range: f64) -> f64 {
        let beyond = if surface.range.is_finite() {
            Self::beyond(surface, rho)
        } else {
            f64::from(rho < max_range)
        };
        match self.risk {
            Some(eps) if beyond < 1.0 - eps => 0.0,
            _ => beyond * origin_step(rho, surface.sigma_origin),
        }
    }

    /// One viewpoint's `P(C occupied)` from the probability `hit` that a
    /// surface lies inside C (any beam) and the fraction `free` of C's volume
    /// its beams certify free (§5.4): `H + (1 − H) (1 − F) / (2 − F)`, the
    /// posterior of "C holds a surface point" with prior ½ and the point
    /// uniformly placed in C, once a fraction F of C is seen empty. Clamped to
    /// `[p_lo, p_hi]`.
    pub fn view_occupancy(&self, hit: f64, free: f64) -> f64 {
        let free = free.clamp(0.0, 1.0);
        let hit = hit.clamp(0.0, 1.0);
        let rest = match self.risk {
            Some(eps) if free < 1.0 - eps => 0.5,
            _ => (1.0 - free) / (2.0 - free),
        };
        (hit + (1.0 - hit) * rest).clamp(self.p_lo, self.p_hi)
    }
}

/// The origin step `Φ(m / σ_o)` (§4.4): how surely range `m` lies in front of
/// the uncertain sensor origin.
#[inline]
pub fn origin_step(m: f64, sigma_origin: f64) -> f64 {
    if m >= TAIL * sigma_origin || sigma_origin <= 0.0 {
        1.0
    } else {
        normal_cdf(m / sigma_origin)
    }
}

/// The chord `[a, b]` (a ≥ 0) of the ray `origin + t·direction`, `t ≥ 0`,
/// through the axis-aligned box `centre ± half`; `None` when it misses.
/// `inverse` is the componentwise inverse of the direction.
#[inline]
pub fn ray_box(
    origin: &Vector3,
    inverse: &Vector3,
    centre: &Vector3,
    half: f64,
) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (0.0f64, f64::INFINITY);
    for axis in 0..3 {
        let o = origin[axis];
        let (near, far) = (centre[axis] - half - o, centre[axis] + half - o);
        let inv = inverse[axis];
        if inv.is_infinite() {
            // Parallel to this slab: inside or never.
            if near > 0.0 || far < 0.0 {
                return None;
            }
            continue;
        }
        let (t0, t1) = (near * inv, far * inv);
        let (t0, t1) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        lo = lo.max(t0);
        hi = hi.min(t1);
        if lo > hi {
            return None;
        }
    }
    Some((lo, hi))
}

#[cfg(test)]
mod tests;
