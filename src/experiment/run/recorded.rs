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
//! \[DESIGN\] A recorded cloud comes without its scanner's raster, which the
//! OPDF merge bins beams by. The raster is recovered from the points: every
//! node gets one angular grid when all its points lie in front of the
//! sensor (+z, the camera convention `sigmap export` writes; the grid is
//! then the simulated scanner's own), else two half-space grids about the
//! axis the points avoid most (a spinning lidar's z). The bin width is the
//! median angular spacing of nearest neighbours, which is the raster step
//! of a regular scanner; `--angular-step` overrides it.

use super::depth_folder::{read_depth_folder, DepthImages};
use crate::error::{Error, Result};
use crate::geometry::{Matrix3, Matrix6, Point3, Pose, Vector3};
use crate::mapping::scan::{
    BeamGrid, BeamLayout, BeamStatus, GridMember, Layouts, MapperView, Measurement, NominalChain,
    Scan, MAX_BEAMS_PER_VIEWPOINT,
};
use crate::mapping::scan_graph::{parse_scan_graph, ScanNode};
use crate::mapping::scan_log::parse_scan_log;
use crate::mapping::settings::MapSettings;
use crate::mapping::spherical::{spherical, Axis};
use crate::mapping::{build_map_with, BuildExtras, Method, Octree};
use crate::sim::profile::{ArmError, ErrorProfile};
use crate::uncertainty::{SigmaSet, UncertainPose};
use rayon::prelude::*;
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
/// grids of [`node_grids`], and its pixels if it came from an image.
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
    let grids = node_grids(node, step)?
        .into_iter()
        .map(NodeGrid::into_beam_grid)
        .collect();
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
        range: &profile.range,
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

/// One angular grid of a node's cloud (docs/math.md §5.6): its frame, its
/// points with their (azimuth, elevation) in it, and its bins.
struct NodeGrid {
    sensor_from_grid: Matrix3,
    members: Vec<usize>,
    angles: Vec<(f64, f64)>,
    azimuth: Axis,
    elevation: Axis,
}

impl NodeGrid {
    /// The grid as a mapper bins beams on it: each point in the bin of its
    /// (azimuth, elevation), the raster slot `row × columns + column`.
    fn into_beam_grid(self) -> BeamGrid {
        let (azimuth, elevation) = (self.azimuth, self.elevation);
        let bin = |angle: f64, axis: &Axis| {
            (((angle - axis.start) / axis.step).floor().max(0.0) as usize).min(axis.count - 1)
        };
        let members = self
            .members
            .iter()
            .zip(&self.angles)
            .map(|(&beam, &(a, e))| GridMember {
                beam,
                slot: bin(e, &elevation) * azimuth.count + bin(a, &azimuth),
            })
            .collect();
        BeamGrid {
            camera_from_grid: self.sensor_from_grid,
            azimuth,
            elevation,
            members: Some(members),
        }
    }
}

/// The angular grids of `node`'s cloud with their bins (`step`: the bin
/// width, else each grid's median spacing).
fn node_grids(node: &ScanNode, step: Option<f64>) -> Result<Vec<NodeGrid>> {
    let mut grids = Vec::new();
    for (sensor_from_grid, members) in grid_frames(&node.points) {
        let angles: Vec<(f64, f64)> = members
            .iter()
            .map(|&i| {
                let (_, az, el) =
                    spherical(&(sensor_from_grid.transpose() * node.points[i].coords));
                (az, el)
            })
            .collect();
        let Some((azimuth, elevation)) = bin_axes(&angles, step)? else {
            continue;
        };
        grids.push(NodeGrid {
            sensor_from_grid,
            members,
            angles,
            azimuth,
            elevation,
        });
    }
    Ok(grids)
}

/// The angular grids of a cloud: `(sensor_from_grid, the points in it)`.
/// Grid x is the boresight and grid z the pole, so that every member has
/// azimuth in [−π/2, π/2] (the grid does not wrap).
pub fn grid_frames(points: &[Point3]) -> Vec<(Matrix3, Vec<usize>)> {
    let valid: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].coords.norm() > 0.0)
        .collect();
    // The camera convention: boresight +z, pole +y (as sigmap's scanner).
    let camera = Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0);
    if valid.iter().all(|&i| points[i].z > 0.0) {
        return vec![(camera, valid)];
    }
    // Else: the pole along the axis the directions avoid most, the
    // boresight along the next axis, and one grid per half-space.
    let mut spread = [0.0f64; 3];
    for &i in &valid {
        let d = points[i].coords.normalize();
        for (s, c) in spread.iter_mut().zip(d.iter()) {
            *s += c * c;
        }
    }
    let pole = (0..3)
        .min_by(|&a, &b| spread[a].total_cmp(&spread[b]))
        .expect("three axes");
    let (boresight, side) = ((pole + 1) % 3, (pole + 2) % 3);
    let axis = |k: usize, sign: f64| Vector3::ith(k, sign);
    let mut front = Vec::new();
    let mut back = Vec::new();
    for &i in &valid {
        if points[i][boresight] >= 0.0 {
            front.push(i);
        } else {
            back.push(i);
        }
    }
    [(1.0, front), (-1.0, back)]
        .into_iter()
        .filter(|(_, members)| !members.is_empty())
        .map(|(sign, members)| {
            let frame =
                Matrix3::from_columns(&[axis(boresight, sign), axis(side, sign), axis(pole, 1.0)]);
            (frame, members)
        })
        .collect()
}

/// The bin width of a grid whose points have no two distinct directions
/// (a single point): any width gives it one bin.
const SINGLE_DIRECTION_STEP: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// The azimuth and elevation bins of a grid holding `angles`: width
/// `step` (else the median nearest-neighbour spacing), the first bin
/// centred on the smallest angle. `None` for no points.
fn bin_axes(angles: &[(f64, f64)], step: Option<f64>) -> Result<Option<(Axis, Axis)>> {
    if angles.is_empty() {
        return Ok(None);
    }
    let step = match step {
        Some(step) => step,
        None => median_spacing(angles).unwrap_or(SINGLE_DIRECTION_STEP),
    };
    let axis = |values: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        let start = lo - step / 2.0;
        let count = ((hi - start) / step).floor() + 1.0;
        (start, count)
    };
    let (az_start, az_count) = axis(&mut angles.iter().map(|a| a.0));
    let (el_start, el_count) = axis(&mut angles.iter().map(|a| a.1));
    if az_count * el_count > MAX_BEAMS_PER_VIEWPOINT {
        return Err(Error::Usage(format!(
            "an angular step of {:.4} deg makes {az_count:.0} x {el_count:.0} bins per scan, \
             more than {MAX_BEAMS_PER_VIEWPOINT:.0}: give a larger --angular-step",
            step.to_degrees()
        )));
    }
    let make = |start, count: f64| Axis {
        start,
        step,
        count: count as usize,
    };
    Ok(Some((make(az_start, az_count), make(el_start, el_count))))
}

/// The median, over the points, of the (azimuth, elevation) distance to
/// the nearest other point: a regular raster's step. `None` when no point
/// has a distinct neighbour.
pub fn median_spacing(angles: &[(f64, f64)]) -> Option<f64> {
    let n = angles.len();
    if n < 2 {
        return None;
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &(a, e) in angles {
        lo = [lo[0].min(a), lo[1].min(e)];
        hi = [hi[0].max(a), hi[1].max(e)];
    }
    let span = [hi[0] - lo[0], hi[1] - lo[1]];
    // A bucket at least one raster step wide (the points of a full raster
    // fill the bounding box; a partial one leaves it emptier, wider buckets).
    let area = span[0] * span[1];
    let bucket = if area > 0.0 {
        (area / n as f64).sqrt()
    } else {
        span[0].max(span[1]) / n as f64
    };
    if bucket.is_nan() || bucket <= 0.0 {
        return None;
    }
    let cell = |a: f64, e: f64| {
        (
            ((a - lo[0]) / bucket).floor() as i64,
            ((e - lo[1]) / bucket).floor() as i64,
        )
    };
    let mut order: Vec<((i64, i64), usize)> = angles
        .iter()
        .enumerate()
        .map(|(i, &(a, e))| (cell(a, e), i))
        .collect();
    order.sort_unstable();
    let mut nearest: Vec<f64> = order
        .par_iter()
        .filter_map(|&((ca, ce), i)| {
            let (a, e) = angles[i];
            let mut best = f64::INFINITY;
            for da in -1..=1 {
                for de in -1..=1 {
                    let key = (ca + da, ce + de);
                    let first = order.partition_point(|(k, _)| *k < key);
                    for &(k, j) in &order[first..] {
                        if k != key {
                            break;
                        }
                        let d = (angles[j].0 - a).hypot(angles[j].1 - e);
                        if d > 1e-12 && d < best {
                            best = d;
                        }
                    }
                }
            }
            best.is_finite().then_some(best)
        })
        .collect();
    if nearest.is_empty() {
        return None;
    }
    let middle = nearest.len() / 2;
    let (_, median, _) = nearest.select_nth_unstable_by(middle, f64::total_cmp);
    Some(*median)
}

#[cfg(test)]
mod tests;
