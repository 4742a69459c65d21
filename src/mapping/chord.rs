//! Cell occupancy from a beam's chord (docs/math.md §5.4): what one beam says
//! about one octree cell.
//!
//! A beam from the mean origin along the unit direction `v` crosses cell C over
//! the range interval `[a, b]` (the chord). The surface it measured lies at
//! `λ ~ N(r, σ²)` along the beam (`σ² = vᵀ Γ_s v`, §4.5). By the first-hit model
//! of §4.7 the surface is inside C, or in front of it (C occluded: prior ½), or
//! beyond it (the beam crossed C: free, `p_lo`):
//!
//! `P(C occ | beam) = P(a ≤ λ ≤ b) + ½ P(λ < a) + q P(λ > b)`, `q = p_lo`,
//!
//! blended with ½ by the origin step `w = Φ(m / σ_o)` at the chord's midpoint
//! `m` (§4.4): `(1 − w) ½ + w P`. With a risk level ε (§5.4) a beam calls C free
//! only when `P(λ > b) ≥ 1 − ε`; otherwise the free event carries no
//! information (`q = ½`). A no-return beam crosses C free when `a` is within
//! the maximum range.

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
    /// Risk level ε: a beam calls a cell free only when `P(λ > b) ≥ 1 − ε`.
    /// `None`: off (every crossed part of a cell counts as free evidence).
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

impl Beam {
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
        if self.range.is_finite() {
            self.range - TAIL * self.sigma
        } else {
            max_range
        }
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
        let chord = if beam.range.is_finite() {
            self.chord(beam.range, beam.sigma, a, b)
        } else {
            self.p_lo
        };
        let mid = 0.5 * (a + b);
        let w = if mid >= TAIL * beam.sigma_origin {
            1.0
        } else if beam.sigma_origin > 0.0 {
            normal_cdf(mid / beam.sigma_origin)
        } else {
            1.0
        };
        Some(((1.0 - w) * 0.5 + w * chord).clamp(self.p_lo, self.p_hi))
    }

    /// The first-hit posterior over the chord, before the origin step.
    fn chord(&self, r: f64, sigma: f64, a: f64, b: f64) -> f64 {
        let (before, after) = if sigma > 0.0 {
            if b < r - TAIL * sigma {
                (0.0, 1.0)
            } else {
                let before = if a < r - TAIL * sigma {
                    0.0
                } else {
                    normal_cdf((a - r) / sigma)
                };
                (before, normal_cdf((r - b) / sigma))
            }
        } else {
            // A hard surface: exactly one of the three events.
            (f64::from(r < a), f64::from(r > b))
        };
        let inside = (1.0 - before - after).max(0.0);
        let q = match self.risk {
            Some(eps) if after < 1.0 - eps => 0.5,
            _ => self.p_lo,
        };
        inside + 0.5 * before + q * after
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
