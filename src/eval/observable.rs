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

/// The most cell steps the rays of one observable mask may walk (their
/// total length over the resolution): its time, a few seconds a 10⁹ steps.
pub const MAX_MASK_STEPS: f64 = 5e9;

/// The most cells one observable mask may hold, 8 bytes each in its hash
/// set (5 × 10⁸: about 4.5 GB at worst).
pub const MAX_MASK_CELLS: f64 = 5e8;

/// Refuses an observable mask whose rays walk more than [`MAX_MASK_STEPS`]
/// cell steps (`steps`: their total length over `resolution`) or may reach
/// more than [`MAX_MASK_CELLS`] cells (`cells`: a bound on the distinct
/// cells they cross, as the boxes they stay in; `steps` when nothing
/// tighter is known). `what` names the rays.
pub fn check_mask_cost(steps: f64, cells: f64, resolution: f64, what: &str) -> Result<(), String> {
    let advice = "use a coarser resolution, fewer beams or a shorter max_range";
    if steps.is_nan() || steps > MAX_MASK_STEPS {
        return Err(format!(
            "{what} cross {steps:.2e} cells at {resolution} m; the observable mask sigmap \
             scores over walks at most {MAX_MASK_STEPS:.0e} ({advice})"
        ));
    }
    let cells = cells.min(steps);
    if cells.is_nan() || cells > MAX_MASK_CELLS {
        return Err(format!(
            "{what} may reach {cells:.2e} cells at {resolution} m; the observable mask sigmap \
             scores over holds at most {MAX_MASK_CELLS:.0e} ({advice})"
        ));
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mask_is_refused_for_its_walk_or_its_cells_not_for_crossing_cells_again() {
        // A dense raster: 1.3e9 steps that stay in 3.8e8 cells.
        assert!(check_mask_cost(1.3e9, 3.8e8, 0.01, "rays").is_ok());
        // Fewer steps than the cubes hold: the steps bound the cells.
        assert!(check_mask_cost(4e8, 1e12, 0.01, "rays").is_ok());
        let walk = check_mask_cost(1e10, 1e8, 0.01, "rays").unwrap_err();
        assert!(walk.contains("rays cross 1.00e10 cells") && walk.contains("walks at most 5e9"));
        let cells = check_mask_cost(1e9, 6e8, 0.01, "rays").unwrap_err();
        assert!(cells.contains("may reach 6.00e8 cells") && cells.contains("holds at most 5e8"));
        assert!(check_mask_cost(f64::NAN, 1.0, 0.01, "rays").is_err());
    }
}
