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
//! [DESIGN] A recorded cloud comes without its scanner's raster, which the
//! OPDF merge bins beams by. The raster is recovered from the points: every
//! node gets one angular grid when all its points lie in front of the
//! sensor (+z, the camera convention `sigmap export` writes; the grid is
//! then the simulated scanner's own), else two half-space grids about the
//! axis the points avoid most (a spinning lidar's z). The bin width is the
//! median angular spacing of nearest neighbours, which is the raster step
//! of a regular scanner; `--angular-step` overrides it.

use super::model::{
    pooled_surface_points, propagator, split_chain, take_shared_motion, Method,
    REGISTERED_TRUTH_FROM_SCANS,
};
use crate::error::{Error, Result};
use crate::geometry::{Matrix3, Matrix6, Point3, Pose, Vector3};
use crate::mapping::merge::merge;
use crate::mapping::octree::Octree;
use crate::mapping::pooling::Pooling;
use crate::mapping::ray_update::RayUpdater;
use crate::mapping::scan_graph::{parse_scan_graph, ScanNode};
use crate::mapping::settings::MapSettings;
use crate::mapping::spherical::{spherical, Axis, BeamEnd, LocalGrid};
use crate::sim::profile::{ArmError, ErrorProfile};
use crate::sim::sensor::{RangeModel, MAX_BEAMS_PER_VIEWPOINT};
use crate::uncertainty::{SigmaSet, UncertainChain, UncertainPoint, UncertainPose};
use rayon::prelude::*;
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

/// Reads and checks a ScanGraph file: every problem (missing, too large,
/// truncated, wrong counts, NaN, no scans) is an error naming the file.
pub fn read_scan_graph(path: &Path) -> Result<Vec<ScanNode>> {
    let size = std::fs::metadata(path)
        .map_err(|e| Error::input(path, format!("cannot read the scan graph: {e}")))?
        .len();
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
    let nodes = parse_scan_graph(&bytes)
        .map_err(|e| Error::input(path, format!("not a valid ScanGraph: {e}")))?;
    if nodes.iter().all(|n| n.points.is_empty()) {
        return Err(Error::input(path, "the scan graph holds no points"));
    }
    Ok(nodes)
}

/// The profile's belief about a recorded node's chain: `T_sw = I`,
/// `T_rw` = the node's pose, `T_cr = I`, with the profile's covariances.
/// Fails when the arm error is given per joint (a graph has no joints).
pub fn node_chain(node: &ScanNode, profile: &ErrorProfile) -> Result<UncertainChain> {
    let arm = arm_covariance(profile)?;
    let uncertain = |mean, covariance| UncertainPose { mean, covariance };
    Ok(UncertainChain::paper(
        uncertain(Pose::identity(), profile.world_from_scene),
        uncertain(Pose::from_isometry(&node.map_from_sensor), arm),
        uncertain(Pose::identity(), profile.robot_from_camera),
    ))
}

fn arm_covariance(profile: &ErrorProfile) -> Result<Matrix6> {
    match &profile.arm {
        ArmError::Pose(covariance) => Ok(*covariance),
        ArmError::Joints(_) => Err(Error::input(
            &profile.source,
            "[world_from_robot] gives joint_sigma, but a scan graph has no joint angles: \
             give the pose error of the scans as [world_from_robot] sigma or covariance",
        )),
    }
}

/// Builds the map of recorded `nodes` (ScanGraph order) with the profile's
/// range model and covariances; `done(k)` after the k-th node.
pub fn map_recorded(
    nodes: &[ScanNode],
    profile: &ErrorProfile,
    settings: &MapSettings,
    options: &RecordedOptions,
    done: impl Fn(usize),
) -> Result<Octree> {
    if options.method == Method::RegisteredTruth {
        return Err(Error::Usage(REGISTERED_TRUTH_FROM_SCANS.into()));
    }
    let chains = nodes
        .iter()
        .map(|node| node_chain(node, profile))
        .collect::<Result<Vec<_>>>()?;
    let max_range = options.max_range.unwrap_or(f64::INFINITY);
    let mut tree = Octree::new(options.resolution);
    if options.method == Method::RayUpdate {
        let mut updater = RayUpdater::new(settings.update);
        for (k, node) in nodes.iter().enumerate() {
            let origin = Point3::from(node.map_from_sensor.translation.vector);
            // With beam pooling a hit's ray ends at its pooled point.
            let measured = match settings.beam_pooling {
                Pooling::Off => None,
                pooling => {
                    let grids = node_grids(node, options.angular_step)?;
                    Some(node_points(
                        node,
                        &grids,
                        &profile.range,
                        pooling,
                        max_range,
                    )?)
                }
            };
            let hits: Vec<Point3> = node
                .points
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let point = measured
                        .as_ref()
                        .and_then(|m| m[i].as_ref())
                        .map_or(*p, |m| Point3::from(m.mean));
                    node.map_from_sensor * point
                })
                .collect();
            updater.insert_scan(&mut tree, &origin, &hits, &[], max_range);
            done(k + 1);
        }
        tree.shrink_to_fit();
        return Ok(tree);
    }
    let merge_options = settings.merge_options();
    for (k, (node, full_chain)) in nodes.iter().zip(&chains).enumerate() {
        let chain = if options.method == Method::Correlated {
            split_chain(full_chain, false)
        } else {
            full_chain.clone()
        };
        // Recorded scans come with a profile, not an experiment: the
        // paper's sigma-point set.
        let propagator =
            propagator(options.method, &chain, SigmaSet::Paper).expect("an OPDF method");
        let origin = propagator.origin();
        let map_from_sensor = chain.nominal().rotation.to_rotation_matrix().into_inner();
        let grids = node_grids(node, options.angular_step)?;
        if settings.interpolate_beams {
            for grid in &grids {
                let bins = grid.azimuth.count as f64 * grid.elevation.count as f64;
                crate::experiment::check_sample_budget(bins).map_err(Error::Usage)?;
            }
        }
        let points = node_points(
            node,
            &grids,
            &profile.range,
            settings.beam_pooling,
            max_range,
        )?;
        for grid in &grids {
            let ends = beam_ends(
                &node.points,
                &grid.members,
                &points,
                &map_from_sensor,
                propagator.as_ref(),
            );
            let mut grid = LocalGrid::new(
                origin.mean,
                map_from_sensor * grid.sensor_from_grid,
                grid.azimuth,
                grid.elevation,
                max_range,
                &ends,
                &origin.covariance,
            );
            if settings.interpolate_beams {
                grid.add_surface_samples();
            }
            merge(&mut tree, &grid, &merge_options);
        }
        done(k + 1);
    }
    if options.method == Method::Correlated {
        take_shared_motion(&mut tree, &chains, &Vector3::zeros(), merge_options.clamp)?;
    }
    tree.shrink_to_fit();
    Ok(tree)
}

/// The propagated ends of the points `members` of a cloud (none at the
/// origin, [`grid_frames`]): a point with a measured point (`points`,
/// [`node_points`]) is a hit, else a no-return beam along its direction.
fn beam_ends(
    cloud: &[Point3],
    members: &[usize],
    points: &[Option<UncertainPoint>],
    map_from_sensor: &Matrix3,
    propagator: &dyn crate::uncertainty::Propagator,
) -> Vec<BeamEnd> {
    members
        .par_iter()
        .map(|&i| match &points[i] {
            Some(point) => {
                let g = propagator.propagate(point);
                BeamEnd::Hit {
                    point: g.mean,
                    covariance: g.covariance,
                }
            }
            None => BeamEnd::Miss {
                direction: map_from_sensor * cloud[i].coords.normalize(),
            },
        })
        .collect()
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

/// The measured point (sensor frame) of each point of `node` within
/// `max_range` (`None`: a beam that returned nothing, or the origin): the
/// point with the range model's covariance, or with `pooling` its range
/// pooled with its neighbours in its grid's raster of bins (docs/math.md
/// §5.5; a regular scanner's raster, one point per bin, §5.6).
fn node_points(
    node: &ScanNode,
    grids: &[NodeGrid],
    range: &RangeModel,
    pooling: Pooling,
    max_range: f64,
) -> Result<Vec<Option<UncertainPoint>>> {
    let mut points: Vec<Option<UncertainPoint>> = node
        .points
        .par_iter()
        .map(|p| {
            let r = p.coords.norm();
            (r > 0.0 && r <= max_range).then(|| UncertainPoint {
                mean: p.coords,
                covariance: range.point_covariance(&(p.coords / r), r),
            })
        })
        .collect();
    if pooling == Pooling::Off {
        return Ok(points);
    }
    for grid in grids {
        let (columns, rows) = (grid.azimuth.count, grid.elevation.count);
        let bin = |angle: f64, axis: &Axis| {
            (((angle - axis.start) / axis.step).floor().max(0.0) as usize).min(axis.count - 1)
        };
        let mut ranges = vec![None; columns * rows];
        let mut directions = vec![Vector3::zeros(); columns * rows];
        let mut slots = Vec::with_capacity(grid.members.len());
        for (&i, &(azimuth, elevation)) in grid.members.iter().zip(&grid.angles) {
            let slot = bin(elevation, &grid.elevation) * columns + bin(azimuth, &grid.azimuth);
            // A slot's direction is set once it holds a point.
            if directions[slot] != Vector3::zeros() {
                return Err(Error::Usage(format!(
                    "beam pooling needs a regular raster, one point per angular bin: scan {} has \
                     two points in one bin of {:.4} deg; give the scanner's step with \
                     --angular-step, or map without --beam-pooling",
                    node.id,
                    grid.azimuth.step.to_degrees()
                )));
            }
            let p = node.points[i].coords;
            let r = p.norm();
            directions[slot] = p / r;
            ranges[slot] = points[i].as_ref().map(|_| r);
            slots.push(slot);
        }
        let pooled = pooled_surface_points(pooling, columns, &directions, &ranges, range);
        for (&i, &slot) in grid.members.iter().zip(&slots) {
            if points[i].is_some() {
                points[i] = pooled[slot];
            }
        }
    }
    Ok(points)
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
