//! The range sensor's error model (docs/math.md §4.5): the range σ as a
//! function of range, the angular jitter, the dropout, and the covariance
//! of a measured point. The simulator draws from it; a mapper is
//! calibrated with it.

use crate::geometry::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Gaussian range error `σ(r) = σ0 + k r + k2 r²` (or a depth camera's
/// `σ(z)` of the depth, [`RangeAxis::Depth`]), independent from beam to
/// beam; an optional scale error shared by every beam of one frame (one
/// viewpoint's scan); optional angular jitter of the true beam direction,
/// optional dropout.
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
    /// Standard deviation of a scale error shared by every beam of a frame
    /// (relative: 0.01 is 1%): each viewpoint's scan draws one `s` and
    /// measures every range `(1 + s)` times too long, as a depth camera's
    /// depth scale drifts with its temperature (docs/math.md §4.5).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub scale_sigma: f64,
    /// What `σ0 + k x + k2 x²` is the error of: the range along the beam
    /// (the default) or a depth camera's depth along its optical axis.
    #[serde(default, skip_serializing_if = "RangeAxis::is_ray")]
    pub along: RangeAxis,
}

/// What a [`RangeModel`]'s `σ0 + k x + k2 x²` measures (docs/math.md §4.5).
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum RangeAxis {
    /// The range along the beam, `x = r`: a laser scanner's time of flight.
    #[default]
    Ray,
    /// The depth along the camera's optical axis (the sensor frame's +z),
    /// `x = z = r cos θ` for a beam `θ` off the axis: a depth camera
    /// triangulates depth, so its pixel's range error is `σ(z) / cos θ`
    /// along the pixel's ray.
    Depth,
}

impl RangeAxis {
    /// Whether this is the default, [`RangeAxis::Ray`].
    pub fn is_ray(&self) -> bool {
        *self == RangeAxis::Ray
    }
}

/// The largest [`RangeModel::scale_sigma`] a profile may give: a tenth of
/// every range, far beyond any depth sensor's drift, and small enough that
/// a frame's scale `1 + s` is never drawn at or below zero (that takes a
/// draw ten standard deviations out).
pub const MAX_SCALE_SIGMA: f64 = 0.1;

/// Whether `v` is zero (what sigmap leaves out when it writes a profile).
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The least cosine between a depth camera's beam and its optical axis
/// (85°): a pinhole's field of view stays well inside it, and beyond it the
/// depth's error along the ray, `σ(z) / cos θ`, says nothing.
pub const MIN_DEPTH_COSINE: f64 = 0.087;

impl RangeModel {
    /// A sensor without noise or dropouts: every range exact, every
    /// direction the nominal one.
    pub const NOISELESS: RangeModel = RangeModel {
        sigma0: 0.0,
        k: 0.0,
        k2: 0.0,
        angular_sigma: 0.0,
        dropout: 0.0,
        scale_sigma: 0.0,
        along: RangeAxis::Ray,
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
            ("scale_sigma", self.scale_sigma, MAX_SCALE_SIGMA),
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

    /// Range standard deviation of the beam along the unit sensor-frame
    /// `direction` at range `r` (docs/math.md §4.5): `σ0 + k r + k2 r²`
    /// along a ray, or for a depth camera `σ(z) / cos θ` with `cos θ = d_z`,
    /// `z = r cos θ`.
    #[inline]
    pub fn sigma(&self, direction: &Vector3, r: f64) -> f64 {
        match self.along {
            RangeAxis::Ray => self.polynomial(r),
            RangeAxis::Depth => {
                let cos = direction.z;
                self.polynomial(r * cos) / cos
            }
        }
    }

    /// The standard deviation, at range `r`, of the frame's shared scale
    /// error: `s_σ r` (the scale is the same along the ray and the depth).
    #[inline]
    pub fn frame_sigma(&self, r: f64) -> f64 {
        self.scale_sigma * r
    }

    /// A range's whole standard deviation as one beam sees it: its own
    /// noise σ (of the pooled range, for a pooled beam) and the frame's
    /// scale error, `√(σ² + (s_σ r)²)`. The scale is shared by the frame's
    /// beams: pooling them averages their own noise, not it.
    #[inline]
    pub fn with_frame_scale(&self, sigma: f64, r: f64) -> f64 {
        if self.scale_sigma == 0.0 {
            // Without a scale error the σ is the beam's own, to the bit.
            sigma
        } else {
            sigma.hypot(self.frame_sigma(r))
        }
    }

    /// `σ0 + k x + k2 x²`.
    #[inline]
    fn polynomial(&self, x: f64) -> f64 {
        // Without k2 the sum is σ0 + k x to the bit.
        self.sigma0 + self.k * x + self.k2 * x * x
    }

    /// Refuses beams a depth camera's error says nothing about: with
    /// [`RangeAxis::Depth`], a sensor-frame direction more than 85° off the
    /// optical axis (+z) or behind it; the caller names the beams' source.
    pub fn check_directions(&self, directions: &[Vector3]) -> Result<(), String> {
        if self.along == RangeAxis::Ray {
            return Ok(());
        }
        match directions.iter().position(|d| {
            let cos = d.z / d.norm();
            cos.is_nan() || cos < MIN_DEPTH_COSINE
        }) {
            Some(i) => Err(format!(
                "beam {i} points {:.1} deg off the optical axis (+z), and [range] along = \
                 \"depth\" (a depth camera's error) holds for beams within 85 deg of it; map it \
                 with a profile whose range error is along the ray",
                (directions[i].z / directions[i].norm())
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
            )),
            None => Ok(()),
        }
    }

    /// Covariance of the measured point `r d` in the laser frame (docs/math.md §4.5):
    /// `σ_r² d dᵀ + r² σ_a² (I − d dᵀ)` for a unit direction `d`.
    pub fn point_covariance(&self, direction: &Vector3, r: f64) -> Matrix3 {
        self.point_covariance_with(direction, r, self.sigma(direction, r))
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
            ..RangeModel::NOISELESS
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
        for scale_sigma in [-1e-3, 0.11, f64::NAN, f64::INFINITY] {
            let message = RangeModel {
                scale_sigma,
                ..model
            }
            .check()
            .unwrap_err();
            assert!(message.contains("scale_sigma"), "{message}");
        }
        assert!(RangeModel {
            scale_sigma: MAX_SCALE_SIGMA,
            ..model
        }
        .check()
        .is_ok());
    }

    /// A depth camera's σ grows as the range squared; without `k2` the
    /// model is the linear one, to the bit.
    #[test]
    fn sigma_grows_with_the_square_of_the_range_by_k2() {
        let linear = RangeModel {
            sigma0: 0.001,
            k: 0.002,
            ..RangeModel::NOISELESS
        };
        let depth_camera = RangeModel {
            k2: 0.004,
            ..linear
        };
        let d = Vector3::new(0.0, 0.6, 0.8);
        for r in [0.3f64, 1.0, 2.5] {
            assert_eq!(linear.sigma(&d, r).to_bits(), (0.001 + 0.002 * r).to_bits());
            let expected = 0.001 + 0.002 * r + 0.004 * r * r;
            assert!((depth_camera.sigma(&d, r) - expected).abs() < 1e-15);
        }
        assert!(depth_camera.check().is_ok());
    }

    /// Along a depth camera's optical axis (+z) its depth σ(z) is the
    /// range's; a pixel θ off the axis at range r has depth z = r cos θ and
    /// range σ(z) / cos θ, which gives the depth z the σ(z) (the range's
    /// error times cos θ). A beam far off the axis, behind it or not a
    /// number is refused, with its angle.
    #[test]
    fn a_depth_cameras_sigma_is_its_depths_on_every_pixel() {
        let depth = RangeModel {
            sigma0: 0.0005,
            k: 0.001,
            k2: 0.0036,
            along: RangeAxis::Depth,
            ..RangeModel::NOISELESS
        };
        let ray = RangeModel {
            along: RangeAxis::Ray,
            ..depth
        };
        let axis = Vector3::z();
        assert_eq!(depth.sigma(&axis, 1.2), ray.sigma(&axis, 1.2));
        let z = 1.5;
        let depth_sigma = 0.0005 + 0.001 * z + 0.0036 * z * z;
        for theta in [0.1f64, 0.5, 0.8] {
            let d = Vector3::new(theta.sin() * 0.6, theta.sin() * 0.8, theta.cos());
            let r = z / theta.cos();
            let along_the_depth = depth.sigma(&d, r) * theta.cos();
            assert!((along_the_depth - depth_sigma).abs() < 1e-15, "{theta}");
            assert!(
                ray.sigma(&d, r) * theta.cos() > depth_sigma + 1e-5,
                "{theta}"
            );
        }
        let pinhole = [axis, Vector3::new(0.6, 0.0, 0.8)];
        assert!(depth.check_directions(&pinhole).is_ok());
        for (bad, angle) in [
            (Vector3::new(1.0, 0.0, 0.05), "87.1 deg"),
            (Vector3::new(0.0, 0.0, -1.0), "180.0 deg"),
            (Vector3::new(f64::NAN, 0.0, 1.0), "NaN deg"),
        ] {
            let message = depth.check_directions(&[axis, bad]).unwrap_err();
            assert!(message.starts_with("beam 1 points"), "{message}");
            assert!(message.contains(angle), "{message}");
            assert!(ray.check_directions(&[axis, bad]).is_ok());
        }
    }

    /// A profile names the depth axis as `along = "depth"`; the default
    /// (the ray) is left out of what sigmap writes, so files without it
    /// read and write as before.
    #[test]
    fn the_axis_reads_from_and_writes_to_a_profiles_range_table() {
        let read = |text: &str| toml::from_str::<RangeModel>(text);
        let depth = read("sigma0 = 0.001\nalong = \"depth\"").unwrap();
        assert_eq!(depth.along, RangeAxis::Depth);
        assert!(toml::to_string(&depth)
            .unwrap()
            .contains("along = \"depth\""));
        let ray = read("sigma0 = 0.001").unwrap();
        assert_eq!(ray.along, RangeAxis::Ray);
        assert!(!toml::to_string(&ray).unwrap().contains("along"));
        // The frame's scale error likewise: absent, none, and not written.
        assert_eq!(ray.scale_sigma, 0.0);
        assert!(!toml::to_string(&ray).unwrap().contains("scale"));
        let scaled = read("sigma0 = 0.001\nscale_sigma = 0.01").unwrap();
        assert_eq!(scaled.scale_sigma, 0.01);
        assert!(toml::to_string(&scaled)
            .unwrap()
            .contains("scale_sigma = 0.01"));
        let message = read("sigma0 = 0.001\nalong = \"optical\"").unwrap_err();
        assert!(message.to_string().contains("ray"), "{message}");
    }
}
