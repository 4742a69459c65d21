//! The occupancy profile along one beam (docs/math.md §4.3–4.4): the designed
//! closed-form D-OPDF with the Gaussian-like step of the uncertain origin.
//!
//! Along the beam line `d = u + λ v` (λ from the mean origin, in metres):
//! `p_surf(λ) = (½ + k_σ) g(λ)` before the measured range `r` and `½ + k_σ g(λ)`
//! after it, `g = exp(−(λ−r)²/2σ²)`, `k_σ = min(k_max, Δ/(σ√(2π)))`; the origin
//! step `p_ext = (1 − w) ½ + w p_surf` with `w = Φ(λ/σ_o)`; the value stored is
//! clamped to `[p_lo, p_hi]` so that log-odds stay finite.

use statrs::function::erf::erfc;

/// How the origin's uncertainty enters (docs/math.md §4.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OriginStep {
    /// `w(λ) = Φ(λ/σ_o)` (the default).
    Cdf,
    /// The alternative reading: `p = ½ exp(−λ²/2σ_o²)` in front, ½ behind.
    Gaussian,
}

/// The profile's constants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpdfParams {
    /// Surface thickness Δ (m), by default the finest voxel edge.
    pub thickness: f64,
    /// Cap of the peak excess over ½ (default 0.48).
    pub k_max: f64,
    /// Lower clamp of stored probabilities (default 0.02).
    pub p_lo: f64,
    /// Upper clamp (default 0.98).
    pub p_hi: f64,
    /// Origin step model.
    pub origin_step: OriginStep,
}

impl OpdfParams {
    /// docs/math.md §4.3's defaults for surface thickness `thickness`.
    pub fn new(thickness: f64) -> Self {
        Self {
            thickness,
            k_max: 0.48,
            p_lo: 0.02,
            p_hi: 0.98,
            origin_step: OriginStep::Cdf,
        }
    }

    /// `k_σ = min(k_max, Δ / (σ √(2π)))`: the peak excess over ½.
    pub fn peak_excess(&self, sigma: f64) -> f64 {
        if sigma <= 0.0 {
            return self.k_max;
        }
        self.k_max
            .min(self.thickness / (sigma * (2.0 * std::f64::consts::PI).sqrt()))
    }

    /// `p_surf(λ)` for measured range `r` and range sigma `σ` along the beam.
    pub fn surface(&self, lambda: f64, r: f64, sigma: f64) -> f64 {
        let k = self.peak_excess(sigma);
        let g = if sigma > 0.0 {
            (-(lambda - r).powi(2) / (2.0 * sigma * sigma)).exp()
        } else if lambda == r {
            1.0
        } else {
            0.0
        };
        if lambda <= r {
            (0.5 + k) * g
        } else {
            0.5 + k * g
        }
    }

    /// `p_ext(λ)`: the profile with the uncertain origin (σ_o along the beam),
    /// before clamping. `r = ∞` gives a no-return beam's free space.
    pub fn extended(&self, lambda: f64, r: f64, sigma: f64, sigma_origin: f64) -> f64 {
        let surface = if r.is_finite() {
            self.surface(lambda, r, sigma)
        } else {
            0.0
        };
        match self.origin_step {
            OriginStep::Cdf => {
                let w = standard_normal_cdf(lambda, sigma_origin);
                (1.0 - w) * 0.5 + w * surface
            }
            OriginStep::Gaussian => {
                if lambda <= 0.0 {
                    0.5
                } else if sigma_origin > 0.0 {
                    let front =
                        0.5 * (-lambda * lambda / (2.0 * sigma_origin * sigma_origin)).exp();
                    // Behind the origin's step the surface profile takes over.
                    front.max(surface)
                } else {
                    surface
                }
            }
        }
    }

    /// The value stored in a grid: `p_ext` clamped to `[p_lo, p_hi]`.
    pub fn stored(&self, lambda: f64, r: f64, sigma: f64, sigma_origin: f64) -> f64 {
        self.extended(lambda, r, sigma, sigma_origin)
            .clamp(self.p_lo, self.p_hi)
    }
}

/// `Φ(x/σ)`, a hard step when `σ = 0`.
fn standard_normal_cdf(x: f64, sigma: f64) -> f64 {
    if sigma <= 0.0 {
        return if x >= 0.0 { 1.0 } else { 0.0 };
    }
    normal_cdf(x / sigma)
}

/// `Φ(x)`, the standard normal CDF.
#[inline]
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * erfc(-x * std::f64::consts::FRAC_1_SQRT_2)
}

/// Log-odds `ln(p / (1 − p))`.
#[inline]
pub fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

/// Probability from log-odds.
#[inline]
pub fn probability(l: f64) -> f64 {
    1.0 / (1.0 + (-l).exp())
}

#[cfg(test)]
mod tests;
