//! What the maps are told of the errors the simulator draws: an
//! experiment's `[believed]` table (docs/math.md §6.7). The simulator draws
//! every error from the experiment's profile; each scan states its pose
//! errors, and the maps are calibrated with a range model, as the believed
//! profile gives them (the experiment's own unless `profile` names
//! another), each σ times a factor. No profile, 1 and 1 (the default) is a
//! calibrated robot; a factor below 1 tells the maps less error than there
//! is (over-confident), above 1 more; another profile tells them errors of
//! another structure (e.g. a fixed pose-space arm error where the arm's is
//! its joints').

use super::profile::ErrorProfile;
use crate::uncertainty::RangeModel;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// An experiment's `[believed]` table.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct BelievedErrors {
    /// The error profile the maps are told (relative to the experiment
    /// file); `None`: the experiment's own, the one the simulator draws.
    #[serde(skip_serializing)]
    pub profile: Option<PathBuf>,
    /// The range σ (`σ0`, `k`, `k2`, the frame's `scale_sigma`) and the
    /// angular σ the maps are calibrated with, times the believed profile's.
    pub sensor_sigma: f64,
    /// Every pose σ the scans state (the arm's, the hand-eye's and the
    /// registration's), times the believed profile's: each stated
    /// covariance is the believed one times `pose_sigma²`.
    pub pose_sigma: f64,
}

impl Default for BelievedErrors {
    fn default() -> Self {
        Self {
            profile: None,
            sensor_sigma: 1.0,
            pose_sigma: 1.0,
        }
    }
}

/// The largest factor: two orders of magnitude either way of the truth is
/// already a robot nobody calibrated.
const MAX_FACTOR: f64 = 100.0;

impl BelievedErrors {
    /// Checks the factors, and the errors they give the believed `profile`'s: the
    /// sensor's between 0.01 and 100 (a range σ of zero would make every
    /// map's surface a step), the poses' between 0 (the scans state no pose
    /// error) and 100; the believed errors within the limits a profile's
    /// are held to. Errors are phrased for the `[believed]` table.
    pub fn check(&self, profile: &ErrorProfile) -> Result<(), String> {
        for (name, value, least) in [
            ("sensor_sigma", self.sensor_sigma, 1.0 / MAX_FACTOR),
            ("pose_sigma", self.pose_sigma, 0.0),
        ] {
            if !value.is_finite() || !(least..=MAX_FACTOR).contains(&value) {
                return Err(format!(
                    "[believed] {name} = {value:e} must be between {least} and {MAX_FACTOR} \
                     (a factor on the profile's sigmas)"
                ));
            }
        }
        let what = format!("[believed] sensor_sigma = {}", self.sensor_sigma);
        self.range(&profile.range)
            .check()
            .map_err(|e| format!("{what} gives {e}"))?;
        let mut poses = profile.clone();
        poses.scale_pose_errors(self.pose_sigma);
        poses.check_pose_magnitudes(&format!(
            "[believed] pose_sigma = {} gives",
            self.pose_sigma
        ))
    }

    /// The range model the maps are calibrated with: `range`'s σ terms (the
    /// frame's scale σ with them) and angular σ times `sensor_sigma`; its
    /// dropout and axis unchanged.
    pub fn range(&self, range: &RangeModel) -> RangeModel {
        let f = self.sensor_sigma;
        RangeModel {
            sigma0: range.sigma0 * f,
            k: range.k * f,
            k2: range.k2 * f,
            angular_sigma: range.angular_sigma * f,
            scale_sigma: range.scale_sigma * f,
            ..*range
        }
    }

    /// What each stated pose covariance is of the drawn one: `pose_sigma²`.
    pub fn pose_variance(&self) -> f64 {
        self.pose_sigma * self.pose_sigma
    }

    /// Whether the maps are told the errors the simulator draws.
    pub fn is_calibrated(&self) -> bool {
        *self == Self::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn profile(name: &str) -> ErrorProfile {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("experiments/profiles")
            .join(name);
        ErrorProfile::load(&path).unwrap()
    }

    /// The believed range model is the profile's with every σ term times the
    /// factor, so that its σ at any range and its angular σ are the
    /// profile's times the factor; a calibrated table gives the profile's to
    /// the bit.
    #[test]
    fn the_believed_sensor_is_the_profiles_scaled() {
        let profile = profile("collaborative.toml");
        let d = crate::geometry::Vector3::new(0.0, 0.6, 0.8);
        let half = BelievedErrors {
            sensor_sigma: 0.5,
            ..BelievedErrors::default()
        };
        let believed = half.range(&profile.range);
        for r in [0.2, 1.0, 3.0] {
            let (told, drawn) = (believed.sigma(&d, r), profile.range.sigma(&d, r));
            assert!((told - 0.5 * drawn).abs() < 1e-15, "{told} {drawn}");
        }
        assert_eq!(believed.angular_sigma, 0.5 * profile.range.angular_sigma);
        let scaled = RangeModel {
            scale_sigma: 0.01,
            ..profile.range
        };
        assert_eq!(half.range(&scaled).scale_sigma, 0.005);
        assert_eq!(believed.dropout, profile.range.dropout);
        assert_eq!(
            BelievedErrors::default().range(&profile.range),
            profile.range
        );
        assert!(BelievedErrors::default().is_calibrated() && !half.is_calibrated());
        let other_profile = BelievedErrors {
            profile: Some("collaborative_poses.toml".into()),
            ..BelievedErrors::default()
        };
        assert!(!other_profile.is_calibrated());
        assert_eq!(
            BelievedErrors {
                pose_sigma: 3.0,
                ..half
            }
            .pose_variance(),
            9.0
        );
    }

    /// Factors outside their bounds, and factors that take the profile's
    /// errors past a profile's limits, are refused, naming the key.
    #[test]
    fn factors_are_checked_against_the_profile() {
        let collaborative = profile("collaborative.toml");
        let check_on = |profile: &ErrorProfile, sensor_sigma: f64, pose_sigma: f64| {
            BelievedErrors {
                sensor_sigma,
                pose_sigma,
                profile: None,
            }
            .check(profile)
        };
        let check = |sensor, pose| check_on(&collaborative, sensor, pose);
        assert!(check(1.0, 1.0).is_ok() && check(0.01, 0.0).is_ok() && check(100.0, 2.0).is_ok());
        for (sensor, pose, key) in [
            (
                0.0,
                1.0,
                "[believed] sensor_sigma = 0e0 must be between 0.01 and 100",
            ),
            (f64::NAN, 1.0, "[believed] sensor_sigma = NaN"),
            (
                1.0,
                -1.0,
                "[believed] pose_sigma = -1e0 must be between 0 and 100",
            ),
            (1.0, 1e3, "[believed] pose_sigma = 1e3"),
        ] {
            let message = check(sensor, pose).unwrap_err();
            assert!(message.starts_with(key), "{message}");
        }
        // The stressed profile's 2 deg of registration error: 20 deg ten
        // times over, within a profile's 0.5 rad; 200 deg a hundred times
        // over, not.
        let stressed = profile("stressed.toml");
        assert!(check_on(&stressed, 1.0, 10.0).is_ok());
        let message = check_on(&stressed, 1.0, 100.0).unwrap_err();
        assert!(
            message.starts_with("[believed] pose_sigma = 100 gives: [world_from_scene]"),
            "{message}"
        );
    }
}
