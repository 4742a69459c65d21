//! Error profiles: the calibrated Gaussian errors of every link of the chain
//! `X_s = T_sw⁻¹ T_rw T_cr X_c` and of the range measurement.

use crate::error::{read_toml_with, Error, Result};
use crate::geometry::Matrix6;
use crate::uncertainty::{check_pose_sigmas, CovarianceSpec, RangeModel, MAX_POSE_SIGMA};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// How the arm's pose error (T_rw) is specified.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // one per experiment; boxing buys nothing
pub enum ArmError {
    /// A covariance on the six pose parameters of `world_from_robot`.
    Pose(Matrix6),
    /// Independent joint-encoder errors (radians or metres per joint),
    /// propagated through forward kinematics: Γ_rw = J Σ_q Jᵀ is full.
    Joints(Vec<f64>),
    /// The same encoder error on every joint, whatever their number
    /// (`joint_sigma = 0.00052`): [`ArmError::Joints`] on the arm it is
    /// given.
    EveryJoint(f64),
}

impl ArmError {
    /// The encoder errors of an arm of `joints` joints, if the error is
    /// given per joint (a list of another length is returned as written,
    /// for the caller to refuse).
    pub fn joint_sigmas(&self, joints: usize) -> Option<Vec<f64>> {
        match self {
            ArmError::Pose(_) => None,
            ArmError::Joints(sigmas) => Some(sigmas.clone()),
            ArmError::EveryJoint(sigma) => Some(vec![*sigma; joints]),
        }
    }

    /// The first joint sigma, as the file writes it, for which `bad` holds,
    /// with the field that holds it (`joint_sigma[i]`, or `joint_sigma` for
    /// one number); `None` for a pose error.
    fn find_joint_sigma(&self, bad: impl Fn(f64) -> bool) -> Option<(String, f64)> {
        match self {
            ArmError::Pose(_) => None,
            ArmError::Joints(sigmas) => sigmas
                .iter()
                .enumerate()
                .find(|(_, s)| bad(**s))
                .map(|(i, s)| (format!("joint_sigma[{i}]"), *s)),
            ArmError::EveryJoint(s) => bad(*s).then(|| ("joint_sigma".into(), *s)),
        }
    }
}

/// `joint_sigma`: one number for every joint, or a list with one per joint.
#[derive(Clone, Debug, PartialEq)]
enum JointSigma {
    Every(f64),
    Each(Vec<f64>),
}

impl<'de> Deserialize<'de> for JointSigma {
    fn deserialize<D: serde::Deserializer<'de>>(
        deserializer: D,
    ) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = JointSigma;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number (the same on every joint) or a list with one per joint")
            }
            fn visit_f64<E>(self, v: f64) -> std::result::Result<JointSigma, E> {
                Ok(JointSigma::Every(v))
            }
            fn visit_i64<E>(self, v: i64) -> std::result::Result<JointSigma, E> {
                Ok(JointSigma::Every(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> std::result::Result<JointSigma, A::Error> {
                Vec::<f64>::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))
                    .map(JointSigma::Each)
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

/// A loaded error profile.
#[derive(Clone, Debug)]
pub struct ErrorProfile {
    /// The profile's name.
    pub name: String,
    /// What it models and where its numbers come from.
    pub description: String,
    /// The file it came from.
    pub source: PathBuf,
    /// Range-measurement errors.
    pub range: RangeModel,
    /// Γ_sw: scene registration (`world_from_scene`).
    pub world_from_scene: Matrix6,
    /// Γ_cr: hand-eye calibration (`robot_from_camera`).
    pub robot_from_camera: Matrix6,
    /// Γ_rw: arm pose (`world_from_robot`).
    pub arm: ArmError,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    name: Option<String>,
    #[serde(default)]
    description: String,
    #[serde(default)]
    sources: Vec<String>,
    range: RangeModel,
    #[serde(default)]
    world_from_scene: CovarianceSpec,
    #[serde(default)]
    robot_from_camera: CovarianceSpec,
    #[serde(default)]
    world_from_robot: ArmSpec,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct ArmSpec {
    sigma: Option<Vec<f64>>,
    covariance: Option<Vec<Vec<f64>>>,
    joint_sigma: Option<JointSigma>,
}

impl ErrorProfile {
    /// Reads and checks a profile file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with(path, &[])
    }

    /// Reads a profile with numeric fields overridden (dotted paths).
    pub fn load_with(path: &Path, overrides: &[(String, toml::Value)]) -> Result<Self> {
        let file: ProfileFile = read_toml_with(path, overrides)?;
        let bad = |msg: String| Error::input(path, msg);
        file.range.check().map_err(bad)?;
        let world_from_scene = file
            .world_from_scene
            .to_matrix::<6>("[world_from_scene]")
            .map_err(bad)?;
        let robot_from_camera = file
            .robot_from_camera
            .to_matrix::<6>("[robot_from_camera]")
            .map_err(bad)?;
        let arm = match file.world_from_robot.joint_sigma {
            Some(sigmas) => {
                if file.world_from_robot.sigma.is_some()
                    || file.world_from_robot.covariance.is_some()
                {
                    return Err(bad(
                        "[world_from_robot]: give `joint_sigma` or a pose `sigma`/`covariance`, not both".into(),
                    ));
                }
                let arm = match sigmas {
                    JointSigma::Every(s) => ArmError::EveryJoint(s),
                    JointSigma::Each(s) => ArmError::Joints(s),
                };
                if let Some((field, s)) = arm.find_joint_sigma(|s| !s.is_finite() || s < 0.0) {
                    return Err(bad(format!(
                        "[world_from_robot]: {field} = {s} must be a finite number >= 0"
                    )));
                }
                arm
            }
            None => ArmError::Pose(
                CovarianceSpec {
                    sigma: file.world_from_robot.sigma,
                    covariance: file.world_from_robot.covariance,
                }
                .to_matrix::<6>("[world_from_robot]")
                .map_err(bad)?,
            ),
        };
        let mut description = file.description;
        for source in &file.sources {
            description.push_str("\nsource: ");
            description.push_str(source);
        }
        Ok(Self {
            name: file.name.unwrap_or_else(|| crate::files::stem(path)),
            description,
            source: path.to_path_buf(),
            range: file.range,
            world_from_scene,
            robot_from_camera,
            arm,
        })
    }
}

impl ErrorProfile {
    /// Multiplies every pose-error standard deviation (T_sw, T_cr, T_rw or its
    /// joint sigmas) by `scale`; the range model is kept.
    pub fn scale_pose_errors(&mut self, scale: f64) {
        let variance = scale * scale;
        self.world_from_scene *= variance;
        self.robot_from_camera *= variance;
        match &mut self.arm {
            ArmError::Pose(c) => *c *= variance,
            ArmError::Joints(s) => s.iter_mut().for_each(|v| *v *= scale),
            ArmError::EveryJoint(s) => *s *= scale,
        }
    }

    /// Checks that every pose error is within the range the additive-angle
    /// model and the statistics handle: translations up to 1 m, angles up to
    /// 0.5 rad (standard deviations). `what` says where the values came from.
    pub fn check_pose_magnitudes(&self, what: &str) -> std::result::Result<(), String> {
        let pose = |name: &str, c: &Matrix6| {
            check_pose_sigmas(c).map_err(|e| format!("{what}: [{name}] {e}"))
        };
        pose("world_from_scene", &self.world_from_scene)?;
        pose("robot_from_camera", &self.robot_from_camera)?;
        if let ArmError::Pose(c) = &self.arm {
            return pose("world_from_robot", c);
        }
        match self
            .arm
            .find_joint_sigma(|s| s.is_nan() || s > MAX_POSE_SIGMA[1])
        {
            Some((field, s)) => Err(format!(
                "{what}: [world_from_robot] {field} = {s:e} exceeds {} rad",
                MAX_POSE_SIGMA[1]
            )),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(body: &str) -> Result<ErrorProfile> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.toml");
        std::fs::write(&path, body).unwrap();
        ErrorProfile::load(&path)
    }

    #[test]
    fn shipped_profiles_load() {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("experiments/profiles");
        for name in ["industrial", "collaborative", "stressed", "quiet_sensor"] {
            let p = ErrorProfile::load(&dir.join(format!("{name}.toml"))).unwrap();
            assert!(!p.description.is_empty(), "{name} documents its sources");
        }
    }

    #[test]
    fn one_joint_sigma_serves_every_joint() {
        let every =
            load("[range]\nsigma0 = 0.001\n[world_from_robot]\njoint_sigma = 0.0005\n").unwrap();
        assert_eq!(every.arm, ArmError::EveryJoint(0.0005));
        assert_eq!(every.arm.joint_sigmas(7), Some(vec![0.0005; 7]));
        let each =
            load("[range]\nsigma0 = 0.001\n[world_from_robot]\njoint_sigma = [1e-4, 2e-4]\n")
                .unwrap();
        assert_eq!(each.arm.joint_sigmas(6), Some(vec![1e-4, 2e-4]));
        for (value, says) in [
            ("-0.1", "joint_sigma = -0.1 must be a finite number >= 0"),
            ("\"small\"", "a number (the same on every joint) or a list"),
        ] {
            let msg = load(&format!(
                "[range]\nsigma0 = 0.001\n[world_from_robot]\njoint_sigma = {value}\n"
            ))
            .unwrap_err()
            .to_string();
            assert!(msg.contains("p.toml") && msg.contains(says), "{msg}");
        }
    }

    #[test]
    fn bad_profiles_are_rejected_with_the_field() {
        let ok = "[range]\nsigma0 = 0.001\n";
        assert!(load(ok).is_ok());
        let msg = load(&format!(
            "{ok}[world_from_robot]\nsigma = [0.001, 0.001, -0.001, 0, 0, 0]\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(
            msg.contains("p.toml")
                && msg.contains("[world_from_robot]")
                && msg.contains("negative"),
            "{msg}"
        );
        let msg = load(&format!(
            "{ok}[robot_from_camera]\nsigma = [nan, 0, 0, 0, 0, 0]\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(msg.contains("finite"), "{msg}");
        let not_pd = "[world_from_scene]\ncovariance = [[1,2,0,0,0,0],[2,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]\n";
        let msg = load(&format!("{ok}{not_pd}")).unwrap_err().to_string();
        assert!(msg.contains("positive semi-definite"), "{msg}");
        assert!(load("[range]\nsigma0 = -0.1\n").is_err());
        assert!(load("[range]\nsigma0 = 0.1\ndropout = 1.5\n").is_err());
        assert!(
            load("[range]\nsigma0 = 0.1\n[world_from_robot]\njoint_sigma = [0.1, -1]\n").is_err()
        );
        assert!(
            load("[range]\nsigma0 = 0.1\n[world_from_robot]\nsgima = [0.1]\n")
                .unwrap_err()
                .to_string()
                .contains("malformed TOML")
        );
    }
}
