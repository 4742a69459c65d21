//! The observable mask (docs/math.md §7.1): cells some true beam of the run
//! could have seen, so that scores separate errors from cells nobody looked at.

use crate::geometry::{Point3, Vector3};
use crate::mapping::octree::Octree;
use crate::mapping::ray_update::ray_keys;
use crate::sim::scan::ScanTruth;
use rustc_hash::FxHashSet;

/// One beam as the mask sees it: from its sensor origin to its end, which is
/// a surface it hit (`hit`) or the point where it left the maximum range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeenRay {
    /// The sensor origin.
    pub origin: Point3,
    /// Where the beam ended.
    pub end: Point3,
    /// Whether it ended on a surface (its end cell was seen too).
    pub hit: bool,
}

/// The most cell steps the rays of one observable mask may take (their
/// total length over the resolution): the mask holds at most that many
/// cells, 8 bytes each in its hash set (5 × 10⁸: about 4.5 GB at worst).
pub const MAX_MASK_STEPS: f64 = 5e8;

/// Refuses rays whose total length at `resolution` passes
/// [`MAX_MASK_STEPS`]: `steps` is that total, `what` names the rays.
pub fn check_mask_steps(steps: f64, resolution: f64, what: &str) -> Result<(), String> {
    if steps <= MAX_MASK_STEPS {
        return Ok(());
    }
    Err(format!(
        "{what} cross {steps:.2e} cells at {resolution} m; the observable mask sigmap scores \
         over takes at most {MAX_MASK_STEPS:.0e} (use a coarser resolution, fewer beams or a \
         shorter max_range)"
    ))
}

/// Morton codes of the cells (at `resolution`) that a ray traversed from its
/// origin to its end, and of its end cell when it hit a surface.
pub fn observable_along(
    rays: impl IntoIterator<Item = SeenRay>,
    resolution: f64,
) -> FxHashSet<u64> {
    let grid = Octree::new(resolution);
    let mut cells = FxHashSet::default();
    let mut keys = Vec::new();
    for ray in rays {
        keys.clear();
        ray_keys(&grid, &ray.origin, &ray.end, &mut keys);
        cells.extend(keys.iter().map(crate::mapping::Key::morton));
        if ray.hit {
            if let Some(k) = grid.key(&ray.end) {
                cells.insert(k.morton());
            }
        }
    }
    cells
}

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
    let rays = truths.into_iter().flat_map(|truth| {
        let pose = &truth.scene_from_camera;
        let origin = Point3::from(pose.translation.vector + offset);
        truth.beams.iter().zip(directions).map(move |(beam, d)| {
            if beam.range.is_nan() {
                SeenRay {
                    origin,
                    end: origin + pose.rotation * d * max_range,
                    hit: false,
                }
            } else {
                SeenRay {
                    origin,
                    end: beam.point + offset,
                    hit: true,
                }
            }
        })
    });
    observable_along(rays, resolution)
}
