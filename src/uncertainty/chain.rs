//! The uncertain transform chain `X_out = T_1 · T_2 ··· T_k · X` (docs/math.md §1.2),
//! any link of which may be inverted, applied to an uncertain point.

use super::{check_pose_sigmas, CovarianceSpec, UncertainPose};
use crate::error::{check_input_file, read_text, read_toml, Error, Result, MAX_TOML_BYTES};
use crate::geometry::{Isometry3, Matrix3, Pose, Vector3};
use serde::Deserialize;
use std::path::Path;

/// One link of a chain: an uncertain pose, used as `T(t)` or `T(t)⁻¹`.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainLink {
    /// A label (`world_from_scene`, ...).
    pub name: String,
    /// The pose parameters and their covariance.
    pub pose: UncertainPose,
    /// The link is the inverse of `pose` (the paper's T_sw⁻¹).
    pub inverse: bool,
}

impl ChainLink {
    /// The link's transform for pose parameters `pose`.
    pub fn transform(&self, pose: &Pose) -> Isometry3 {
        let t = pose.to_isometry();
        if self.inverse {
            t.inverse()
        } else {
            t
        }
    }
}

/// A measured point with its covariance, in the chain's last frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UncertainPoint {
    /// Mean (m).
    pub mean: Vector3,
    /// Covariance (m²).
    pub covariance: Matrix3,
}

/// A Gaussian estimate of a point in the output frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gaussian3 {
    /// Mean (m).
    pub mean: Vector3,
    /// Covariance (m²).
    pub covariance: Matrix3,
}

impl Default for Gaussian3 {
    fn default() -> Self {
        Self {
            mean: Vector3::zeros(),
            covariance: Matrix3::zeros(),
        }
    }
}

/// The chain `T_1 ··· T_k`, listed left to right as in the formula: `T_1` maps
/// into the output frame, `T_k` takes the measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct UncertainChain {
    /// The links, left to right.
    pub links: Vec<ChainLink>,
}

impl UncertainChain {
    /// The paper's chain `T_sw⁻¹ · T_rw · T_cr`.
    pub fn paper(
        world_from_scene: UncertainPose,
        world_from_robot: UncertainPose,
        robot_from_camera: UncertainPose,
    ) -> Self {
        let link = |name: &str, pose, inverse| ChainLink {
            name: name.into(),
            pose,
            inverse,
        };
        Self {
            links: vec![
                link("world_from_scene", world_from_scene, true),
                link("world_from_robot", world_from_robot, false),
                link("robot_from_camera", robot_from_camera, false),
            ],
        }
    }

    /// The nominal chain transform (every link at its mean).
    pub fn nominal(&self) -> Isometry3 {
        self.evaluate(|i| self.links[i].pose.mean)
    }

    /// The chain transform with link `i` at pose `pose(i)`.
    pub fn evaluate(&self, pose: impl Fn(usize) -> Pose) -> Isometry3 {
        self.links
            .iter()
            .enumerate()
            .fold(Isometry3::identity(), |acc, (i, link)| {
                acc * link.transform(&pose(i))
            })
    }

    /// Number of uncertain parameters: 6 per link plus 3 for the point.
    pub fn parameter_count(&self) -> usize {
        6 * self.links.len() + 3
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ChainFile {
    #[serde(rename = "transform")]
    transforms: Vec<TransformSpec>,
    point: Option<PointSpec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TransformSpec {
    name: Option<String>,
    #[serde(default)]
    xyz: [f64; 3],
    #[serde(default)]
    rpy: [f64; 3],
    #[serde(default)]
    inverse: bool,
    sigma: Option<Vec<f64>>,
    covariance: Option<Vec<Vec<f64>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PointSpec {
    xyz: [f64; 3],
    sigma: Option<Vec<f64>>,
    covariance: Option<Vec<Vec<f64>>>,
}

fn spec(sigma: Option<&Vec<f64>>, covariance: Option<&Vec<Vec<f64>>>) -> CovarianceSpec {
    CovarianceSpec {
        sigma: sigma.cloned(),
        covariance: covariance.cloned(),
    }
}

/// Whether `path` reads as an experiment file (TOML with a `scene` and a
/// `[robot]`), given where a chain file belongs; read only within the size
/// any TOML input may have.
fn is_experiment(path: &Path) -> bool {
    if check_input_file(path, MAX_TOML_BYTES).is_err() {
        return false;
    }
    read_text(path).is_ok_and(|text| {
        toml::from_str::<toml::Table>(&text)
            .is_ok_and(|table| table.contains_key("scene") && table.contains_key("robot"))
    })
}

/// The farthest a chain file's translation or point may lie from its frame's
/// origin (m): 10 000 km, so that a world frame on the Earth (UTM
/// coordinates, say) is taken and `1e308` is not.
pub const MAX_CHAIN_REACH: f64 = 1e7;

/// The largest standard deviation of a chain file's point (m), as of a
/// profile's range noise.
const MAX_POINT_SIGMA: f64 = 1.0;

/// Whether `xyz` is finite and within [`MAX_CHAIN_REACH`] on every axis; the
/// error names `what` and the limit.
pub fn check_reach(xyz: &[f64; 3], what: &str) -> std::result::Result<(), String> {
    match xyz
        .iter()
        .find(|v| !v.is_finite() || v.abs() > MAX_CHAIN_REACH)
    {
        Some(v) if !v.is_finite() => Err(format!("{what} xyz must be finite, found {v}")),
        Some(v) => Err(format!(
            "{what} xyz has {v:e} m, farther than {MAX_CHAIN_REACH:e} m from the origin"
        )),
        None => Ok(()),
    }
}

/// Reads a chain file (the `sigmap propagate` format, see docs/cli.md): the chain
/// and, if the file has a `[point]`, the measurement. Translations and the
/// point lie within [`MAX_CHAIN_REACH`]; each link's standard deviations are
/// at most [`MAX_POSE_SIGMA`](super::MAX_POSE_SIGMA), the point's at most 1 m.
pub fn read_chain_file(path: &Path) -> Result<(UncertainChain, Option<UncertainPoint>)> {
    let bad = |msg: String| Error::input(path, msg);
    let file: ChainFile = read_toml(path).map_err(|e| {
        if is_experiment(path) {
            bad(
                "is an experiment file; `sigmap propagate` takes a chain file ([[transform]]s \
                 and a [point], docs/cli.md \"Chain file\")"
                    .into(),
            )
        } else {
            e
        }
    })?;
    if file.transforms.is_empty() {
        return Err(bad("the chain has no [[transform]]".into()));
    }
    let mut links = Vec::with_capacity(file.transforms.len());
    for (i, t) in file.transforms.iter().enumerate() {
        let name = t.name.clone().unwrap_or_else(|| format!("transform {i}"));
        let what = format!("[[transform]] '{name}'");
        let mean = Pose::new(t.xyz, t.rpy);
        if !mean.is_finite() {
            return Err(bad(format!("{what}: xyz/rpy must be finite")));
        }
        check_reach(&t.xyz, &format!("{what}:")).map_err(bad)?;
        let covariance = spec(t.sigma.as_ref(), t.covariance.as_ref())
            .to_matrix::<6>(&what)
            .map_err(bad)?;
        check_pose_sigmas(&covariance).map_err(|e| bad(format!("{what}: {e}")))?;
        links.push(ChainLink {
            name,
            pose: UncertainPose { mean, covariance },
            inverse: t.inverse,
        });
    }
    let point = match file.point {
        None => None,
        Some(p) => {
            check_reach(&p.xyz, "[point]").map_err(bad)?;
            let covariance = spec(p.sigma.as_ref(), p.covariance.as_ref())
                .to_matrix::<3>("[point]")
                .map_err(bad)?;
            let sigmas = covariance.diagonal().map(|v| v.max(0.0).sqrt());
            if let Some((i, s)) = sigmas
                .iter()
                .enumerate()
                .find(|(_, s)| **s > MAX_POINT_SIGMA)
            {
                return Err(bad(format!(
                    "[point]: sigma[{i}] = {s:e} exceeds {MAX_POINT_SIGMA} m"
                )));
            }
            Some(UncertainPoint {
                mean: Vector3::from(p.xyz),
                covariance,
            })
        }
    };
    Ok((UncertainChain { links }, point))
}
