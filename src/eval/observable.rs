//! The observable mask (docs/math.md §7.1): cells some true beam of the run
//! could have seen, so that scores separate errors from cells nobody looked at.

use crate::geometry::{Point3, Vector3};
use crate::mapping::octree::Octree;
use crate::mapping::ray_update::ray_keys;
use crate::sim::scan::ScanTruth;
use rustc_hash::FxHashSet;

/// Morton codes of the cells (at `resolution`) that a true beam traversed,
/// or whose surface it hit, from the true sensor origin: up to the true hit,
/// or up to the maximum range for beams that reached nothing; in the map
/// frame `map = scene + offset`. `directions` are the scanner's beam
/// directions in the laser frame, `truths` the scans' truth.
pub fn observable_cells<'a>(
    directions: &[Vector3],
    max_range: f64,
    truths: impl IntoIterator<Item = &'a ScanTruth>,
    resolution: f64,
    offset: &Vector3,
) -> FxHashSet<u64> {
    let grid = Octree::new(resolution);
    let mut cells = FxHashSet::default();
    let mut ray = Vec::new();
    for truth in truths {
        let pose = &truth.scene_from_camera;
        let origin = Point3::from(pose.translation.vector + offset);
        for (beam, d) in truth.beams.iter().zip(directions) {
            let end = if beam.range.is_nan() {
                origin + pose.rotation * d * max_range
            } else {
                beam.point + offset
            };
            ray.clear();
            ray_keys(&grid, &origin, &end, &mut ray);
            cells.extend(ray.iter().map(|k| k.morton()));
            if !beam.range.is_nan() {
                if let Some(k) = grid.key(&end) {
                    cells.insert(k.morton());
                }
            }
        }
    }
    cells
}
