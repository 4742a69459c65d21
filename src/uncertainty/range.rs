//! The range sensor's error model (docs/math.md §4.5): the range σ as a
//! function of range, the angular jitter, the dropout, and the covariance
//! of a measured point. The simulator draws from it; a mapper is
//! calibrated with it.

use crate::geometry::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Gaussian range error `σ(r) = σ0 + k r + k2 r²`, optional angular jitter of
/// the true beam direction, optional dropout.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RangeModel {
    /// Constant part of the range standard deviation (m).
    pub sigma0: f64,
    /// Growth of the standard deviation with range (m per m).
    #[serde(default)]
    pub k: f64,
    /// Growth with the square of the range (m per m²): a stereo or
    /// structured-light depth camera's error, which triangulation makes
    /// grow as its range squared.
    #[serde(default)]
    pub k2: f64,
    /// Standard deviation of the beam direction about each of its two
    /// perpendicular axes (radians).
    #[serde(default)]
    pub angular_sigma: f64,
    /// Probability that a beam that hits returns nothing.
    #[serde(default)]
    pub dropout: f64,
}

impl RangeModel {
    /// A sensor without noise or dropouts: every range exact, every
    /// direction the nominal one.
    pub const NOISELESS: RangeModel = RangeModel {
        sigma0: 0.0,
        k: 0.0,
        k2: 0.0,
        angular_sigma: 0.0,
        dropout: 0.0,
    };

    /// Checks the numbers; errors are phrased for the `[range]` table.
    pub fn check(&self) -> Result<(), String> {
        // Beyond these a "range sensor" says nothing and the statistics
        // overflow: a metre of noise, a metre per metre (or per m²), half a
        // radian.
        for (name, value, limit) in [
            ("sigma0", self.sigma0, 1.0),
            ("k", self.k, 1.0),
            ("k2", self.k2, 1.0),
            ("angular_sigma", self.angular_sigma, 0.5),
        ] {
            if !value.is_finite() || !(0.0..=limit).contains(&value) {
                return Err(format!(
                    "[range] {name} = {value:e} must be between 0 and {limit}"
                ));
            }
        }
        if !(0.0..1.0).contains(&self.dropout) {
            return Err(format!(
                "[range] dropout = {} must be a probability in [0, 1)",
                self.dropout
            ));
        }
        Ok(())
    }

    /// Range standard deviation at range `r`: `σ0 + k r + k2 r²`.
    #[inline]
    pub fn sigma(&self, r: f64) -> f64 {
        // Without k2 the sum is σ0 + k r to the bit.
        self.sigma0 + self.k * r + self.k2 * r * r
    }

    /// Covariance of the measured point `r d` in the laser frame (docs/math.md §4.5):
    /// `σ_r² d dᵀ + r² σ_a² (I − d dᵀ)` for a unit direction `d`.
    pub fn point_covariance(&self, direction: &Vector3, r: f64) -> Matrix3 {
        self.point_covariance_with(direction, r, self.sigma(r))
    }

    /// The same with the range standard deviation `sr` given (a pooled range).
    pub fn point_covariance_with(&self, direction: &Vector3, r: f64, sr: f64) -> Matrix3 {
        let ddt = direction * direction.transpose();
        ddt * (sr * sr)
            + (Matrix3::identity() - ddt) * (r * r * self.angular_sigma * self.angular_sigma)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_covariance_has_range_and_lateral_parts() {
        let model = RangeModel {
            sigma0: 0.001,
            k: 0.002,
            k2: 0.0,
            angular_sigma: 0.001,
            dropout: 0.0,
        };
        let d = Vector3::new(0.0, 0.6, 0.8);
        let c = model.point_covariance(&d, 2.0);
        assert!(((d.transpose() * c * d)[0] - 0.005f64.powi(2)).abs() < 1e-15);
        let lateral = Vector3::x();
        assert!(((lateral.transpose() * c * lateral)[0] - 4e-6).abs() < 1e-15);
        assert!(RangeModel {
            dropout: 1.0,
            ..model
        }
        .check()
        .is_err());
        assert!(RangeModel {
            sigma0: -1.0,
            ..model
        }
        .check()
        .is_err());
        for k2 in [-1e-3, 2.0, f64::NAN] {
            let message = RangeModel { k2, ..model }.check().unwrap_err();
            assert!(message.contains("k2"), "{message}");
        }
    }

    /// A depth camera's σ grows as the range squared; without `k2` the
    /// model is the linear one, to the bit.
    #[test]
    fn sigma_grows_with_the_square_of_the_range_by_k2() {
        let linear = RangeModel {
            sigma0: 0.001,
            k: 0.002,
            k2: 0.0,
            angular_sigma: 0.0,
            dropout: 0.0,
        };
        let depth_camera = RangeModel {
            k2: 0.004,
            ..linear
        };
        for r in [0.3, 1.0, 2.5] {
            assert_eq!(linear.sigma(r).to_bits(), (0.001 + 0.002 * r).to_bits());
            let expected = 0.001 + 0.002 * r + 0.004 * r * r;
            assert!((depth_camera.sigma(r) - expected).abs() < 1e-15);
        }
        assert!(depth_camera.check().is_ok());
    }
}
