//! The angular grids of a cloud of points whose scanner's raster is not
//! known (docs/math.md §5.6): a recorded scan's, or a pinhole camera's,
//! whose pixels are not evenly spaced in angle.
//!
//! \[DESIGN\] The OPDF merge bins beams on angular grids. A cloud gets one
//! grid when all its points lie in front of the sensor (+z, the camera
//! convention `sigmap export` writes; the grid is then the simulated
//! scanner's own), else two half-space grids about the axis the points
//! avoid most (a spinning lidar's z). The bin width is the median angular
//! spacing of nearest neighbours, which is the raster step of a regular
//! scanner, unless one is given.

use super::scan::{BeamGrid, GridMember, MAX_BEAMS_PER_VIEWPOINT};
use super::spherical::{spherical, Axis};
use crate::geometry::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

/// One angular grid of a cloud (docs/math.md §5.6): its frame, its
/// points with their (azimuth, elevation) in it, and its bins.
struct CloudGrid {
    sensor_from_grid: Matrix3,
    members: Vec<usize>,
    angles: Vec<(f64, f64)>,
    azimuth: Axis,
    elevation: Axis,
}

impl CloudGrid {
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

/// `(azimuth, elevation)` of each of `members` of `points` in the grid
/// frame `sensor_from_grid` gives.
fn grid_angles(
    points: &[Point3],
    sensor_from_grid: &Matrix3,
    members: &[usize],
) -> Vec<(f64, f64)> {
    let grid_from_sensor = sensor_from_grid.transpose();
    members
        .iter()
        .map(|&i| {
            let (_, az, el) = spherical(&(grid_from_sensor * points[i].coords));
            (az, el)
        })
        .collect()
}

/// The angular grids of a cloud of `points` (sensor frame) with their bins
/// (`step`: the bin width, else each grid's median spacing), each point in
/// the bin of its direction. Fails, before allocating them, when the bins
/// would be too many.
pub fn cloud_grids(points: &[Point3], step: Option<f64>) -> Result<Vec<BeamGrid>, String> {
    let mut grids = Vec::new();
    for (sensor_from_grid, members) in grid_frames(points) {
        let angles = grid_angles(points, &sensor_from_grid, &members);
        let Some((azimuth, elevation)) = bin_axes(&angles, step)? else {
            continue;
        };
        let grid = CloudGrid {
            sensor_from_grid,
            members,
            angles,
            azimuth,
            elevation,
        };
        grids.push(grid.into_beam_grid());
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
fn bin_axes(angles: &[(f64, f64)], step: Option<f64>) -> Result<Option<(Axis, Axis)>, String> {
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
        return Err(format!(
            "an angular step of {:.4} deg makes {az_count:.0} x {el_count:.0} bins per scan, \
             more than {MAX_BEAMS_PER_VIEWPOINT:.0}: give a larger --angular-step",
            step.to_degrees()
        ));
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
pub(crate) mod tests;
