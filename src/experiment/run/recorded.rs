//! Maps of scans recorded elsewhere (`sigmap map --scans`): the nodes of an
//! OctoMap ScanGraph, believed through an error profile, mapped with any
//! method. Real data has no ground truth: this builds the map only.
//!
//! Each node's pose is taken as `T_rw` (the arm's pose) with the profile's
//! arm covariance on its (x, y, z, roll, pitch, yaw), between an identity
//! `T_sw` (map = scene) and an identity `T_cr` that carry the profile's
//! registration and hand-eye covariances (docs/math.md §5.6). A point `p` of
//! the node's cloud is a beam of direction `p / |p|` and range `|p|` with the
//! profile's range and angular noise.
//!
//! A recorded cloud comes without its scanner's raster, which the OPDF
//! merge bins beams by: it is recovered from the points
//! ([`crate::mapping::cloud_grids`]); `--angular-step` sets the bin width.

use super::depth_folder::{read_depth_folder, DepthImages};
use crate::error::{Error, Result};
use crate::geometry::{Matrix6, Point3, Pose, Vector3};
use crate::mapping::cloud_grids::cloud_grids;
use crate::mapping::scan::{
    BeamLayout, BeamStatus, Layouts, MapperView, Measurement, NominalChain, Scan,
};
use crate::mapping::scan_graph::{parse_scan_graph, ScanNode};
use crate::mapping::scan_log::parse_scan_log;
use crate::mapping::settings::MapSettings;
use crate::mapping::{build_map_with, BuildExtras, Method, Octree};
use crate::sim::profile::{ArmError, ErrorProfile};
use crate::uncertainty::{SigmaSet, UncertainPose};
use std::io::Read as _;
use std::path::Path;

/// How recorded scans are mapped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordedOptions {
    /// The mapping method.
    pub method: Method,
    /// Finest voxel edge (m).
    pub resolution: f64,
    /// `graph2tree -m`: a point farther than this is a beam that returned
    /// nothing, clearing free space up to it; `None`: every point is a hit.
    pub max_range: Option<f64>,
    /// Angular bin width of the OPDF grids (rad); `None`: estimated per
    /// grid from the points.
    pub angular_step: Option<f64>,
}

/// The largest graph file read (bytes): its points are held in memory,
/// about as many bytes as the file.
pub const MAX_GRAPH_BYTES: u64 = 8 << 30;

/// The largest plain-text scan log `sigmap map --scans` reads: its points
/// take up to four times its bytes in memory (`0 0 0` is six bytes, a
/// point 24), so as much as the largest graph's.
pub const MAX_LOG_BYTES: u64 = 2 << 30;

/// The most points mapped at once. While scans are mapped each point takes
/// about 80 bytes (its point, its beam and its direction; measured 75–85
/// on a folder of depth images), so this is about 8 GB beside a map of at
/// most [`crate::mapping::build::MAX_MAP_BYTES`].
pub const MAX_RECORDED_POINTS: u64 = 100_000_000;

/// Refuses `count` points read from `path` past [`MAX_RECORDED_POINTS`].
fn check_point_count(path: &Path, count: u64) -> Result<()> {
    if count > MAX_RECORDED_POINTS {
        return Err(Error::input(
            path,
            format!(
                "{count} points: sigmap maps at most {MAX_RECORDED_POINTS} at once (about 80 \
                 bytes each while mapping): split the scans"
            ),
        ));
    }
    Ok(())
}

/// Reads and checks recorded scans: a folder of depth images with their
/// trajectory ([`read_depth_folder`]), or a file as [`read_scan_graph`]
/// reads it; with the notes to print (images left without a pose). Scans
/// without a point, or of more than [`MAX_RECORDED_POINTS`], are refused.
pub fn read_scans(path: &Path, depth: &DepthImages) -> Result<(Vec<ScanNode>, Vec<String>)> {
    let (nodes, notes, empty) = if path.is_dir() {
        let (nodes, notes) = read_depth_folder(path, depth)?;
        (nodes, notes, "the depth images hold no depth")
    } else if *depth != DepthImages::default() {
        return Err(Error::Usage(format!(
            "--intrinsics, --depth-scale, --trajectory and --every are for a folder of depth \
             images; {} is not a folder",
            path.display()
        )));
    } else {
        (
            read_scan_graph(path)?,
            Vec::new(),
            "the scans hold no points",
        )
    };
    if nodes.iter().all(|n| n.points.is_empty()) {
        return Err(Error::input(path, empty));
    }
    let count = nodes.iter().map(|n| n.points.len() as u64).sum();
    check_point_count(path, count)?;
    Ok((nodes, notes))
}

/// Reads an OctoMap ScanGraph, or the plain-text log `log2graph` reads
/// (`mapping::scan_log`), told apart by their first bytes (a graph's node
/// count holds a zero byte; text holds none). Every problem (missing, too
/// large, truncated, wrong counts, NaN, a bad line) is an error naming the
/// file; [`read_scans`] checks what the nodes hold.
fn read_scan_graph(path: &Path) -> Result<Vec<ScanNode>> {
    let meta = std::fs::metadata(path)
        .map_err(|e| Error::input(path, format!("cannot read the scans: {e}")))?;
    if !meta.is_file() {
        // A device or a pipe would be read forever.
        return Err(Error::input(path, "is not a regular file"));
    }
    let size = meta.len();
    let mut file = std::fs::File::open(path)
        .map_err(|e| Error::input(path, format!("cannot read the scans: {e}")))?;
    let mut head = Vec::with_capacity(4);
    std::io::Read::by_ref(&mut file)
        .take(4)
        .read_to_end(&mut head)
        .map_err(|e| Error::input(path, format!("cannot read the scans: {e}")))?;
    let nodes = if head.len() == 4 && head.contains(&0) {
        read_binary_graph(path, size)?
    } else {
        read_log(path, size)?
    };
    Ok(nodes)
}

/// The nodes of the ScanGraph at `path` (`size` bytes).
fn read_binary_graph(path: &Path, size: u64) -> Result<Vec<ScanNode>> {
    if size > MAX_GRAPH_BYTES {
        return Err(Error::input(
            path,
            format!(
                "{size} bytes: sigmap maps graphs of at most {MAX_GRAPH_BYTES} bytes; \
                 split the graph"
            ),
        ));
    }
    let bytes = std::fs::read(path)
        .map_err(|e| Error::input(path, format!("cannot read the scan graph: {e}")))?;
    parse_scan_graph(&bytes).map_err(|e| Error::input(path, format!("not a valid ScanGraph: {e}")))
}

/// The nodes of the plain-text scan log at `path` (`size` bytes).
fn read_log(path: &Path, size: u64) -> Result<Vec<ScanNode>> {
    if size > MAX_LOG_BYTES {
        return Err(Error::input(
            path,
            format!(
                "{size} bytes of text: sigmap reads scan logs of at most {MAX_LOG_BYTES} \
                 bytes; split the log, or turn it into a ScanGraph with OctoMap's log2graph"
            ),
        ));
    }
    let file = std::fs::File::open(path)
        .map_err(|e| Error::input(path, format!("cannot read the scan log: {e}")))?;
    parse_scan_log(std::io::BufReader::new(file))
        .map_err(|e| Error::input(path, format!("not a valid scan log: {e}")))
}

/// The profile's belief about a recorded node's chain: `T_sw = I`,
/// `T_rw` = the node's pose, `T_cr = I`, with the profile's covariances.
/// Fails when the arm error is given per joint (a graph has no joints).
pub fn node_chain(node: &ScanNode, profile: &ErrorProfile) -> Result<NominalChain> {
    let arm = arm_covariance(profile)?;
    let uncertain = |mean, covariance| UncertainPose { mean, covariance };
    Ok(NominalChain {
        world_from_scene: uncertain(Pose::identity(), profile.world_from_scene),
        world_from_robot: uncertain(Pose::from_isometry(&node.map_from_sensor), arm),
        robot_from_camera: uncertain(Pose::identity(), profile.robot_from_camera),
    })
}

fn arm_covariance(profile: &ErrorProfile) -> Result<Matrix6> {
    match &profile.arm {
        ArmError::Pose(covariance) => Ok(*covariance),
        ArmError::Joints(_) | ArmError::EveryJoint(_) => Err(Error::input(
            &profile.source,
            "[world_from_robot] gives joint_sigma, but a scan graph has no joint angles: \
             give the pose error of the scans as [world_from_robot] sigma or covariance",
        )),
    }
}

/// The scans a mapper sees of recorded `nodes` (ScanGraph order), believed
/// through the profile ([`node_chain`]), with each one's beam layout: its
/// points as beams (a point farther than `max_range` is a beam that returned
/// nothing; one at the origin carries nothing) binned on the grids recovered
/// from the cloud (`angular_step`: their bin width, else each grid's median
/// spacing; docs/math.md §5.6).
pub fn recorded_scans(
    nodes: &[ScanNode],
    profile: &ErrorProfile,
    max_range: f64,
    angular_step: Option<f64>,
) -> Result<(Vec<Scan>, Vec<BeamLayout>)> {
    let mut scans = Vec::with_capacity(nodes.len());
    let mut layouts = Vec::with_capacity(nodes.len());
    for node in nodes {
        let measurements = node
            .points
            .iter()
            .map(|p| point_measurement(p, max_range))
            .collect();
        scans.push(Scan {
            viewpoint: node.id as usize,
            joints: Vec::new(),
            chain: node_chain(node, profile)?,
            measurements,
        });
        layouts.push(node_layout(node, angular_step)?);
    }
    Ok((scans, layouts))
}

/// A recorded point as a beam's measurement: a hit at its range, or beyond
/// `max_range` a beam that returned nothing (its range kept: OctoMap's
/// update carves toward it up to `max_range`); a point at the origin is a
/// beam too close to measure.
fn point_measurement(p: &Point3, max_range: f64) -> Measurement {
    let r = p.coords.norm();
    let status = if r == 0.0 {
        BeamStatus::TooClose
    } else if r <= max_range {
        BeamStatus::Hit
    } else {
        BeamStatus::NoReturn
    };
    Measurement { status, range: r }
}

/// The beam layout of a node's cloud: each point's direction, binned on the
/// grids of [`cloud_grids`], and its pixels if it came from an image.
fn node_layout(node: &ScanNode, step: Option<f64>) -> Result<BeamLayout> {
    let directions = node
        .points
        .iter()
        .map(|p| {
            let r = p.coords.norm();
            if r > 0.0 {
                p.coords / r
            } else {
                Vector3::zeros()
            }
        })
        .collect();
    let grids = cloud_grids(&node.points, step).map_err(Error::Usage)?;
    Ok(BeamLayout {
        directions,
        grids,
        half_angles: None,
        pixels: node.pixels.clone(),
    })
}

/// Builds the map of recorded `nodes` (ScanGraph order) with the profile's
/// range model and covariances: [`recorded_scans`] mapped by the one map
/// builder; `done(k)` after the k-th node. A profile with an absurd pose
/// error is refused, as an experiment's is.
pub fn map_recorded(
    nodes: &[ScanNode],
    profile: &ErrorProfile,
    settings: &MapSettings,
    options: &RecordedOptions,
    done: impl Fn(usize) + Sync,
) -> Result<Octree> {
    profile
        .check_pose_magnitudes("the profile")
        .map_err(|e| Error::input(&profile.source, e))?;
    let max_range = options.max_range.unwrap_or(f64::INFINITY);
    let (scans, layouts) = recorded_scans(nodes, profile, max_range, options.angular_step)?;
    let view = MapperView {
        layouts: Layouts::PerScan(&layouts),
        range: profile.range,
        max_range,
        settings,
        // Recorded scans come with a profile, not an experiment: the
        // paper's sigma-point set.
        sigma_set: SigmaSet::Paper,
    };
    let extras = BuildExtras {
        measured: None,
        done: Some(&done),
        max_bytes: None,
        phases: None,
    };
    build_map_with(
        &view,
        &scans,
        extras,
        options.method,
        options.resolution,
        &Vector3::zeros(),
    )
}

#[cfg(test)]
mod tests;
