//! OctoMap's discretized insertion (`insertPointCloud(..., discretize =
//! true)`, its `computeDiscreteUpdate`): a scan's points reduced to one per
//! finest cell, each moved to its cell's centre, before the usual update
//! (docs/octomap.md, "Discretized insertion").

use super::float;
use crate::geometry::{Point3, Vector3};
use crate::mapping::octree::Octree;
use rustc_hash::FxHashSet;

/// One scan's end points as OctoMap's discretized insertion casts them, in
/// buffers kept for the next scan.
#[derive(Default)]
pub struct DiscreteScan {
    /// The end cells met so far ([`Key::packed`](super::Key::packed)).
    cells: FxHashSet<u64>,
    /// The cells met last, one per slot of a hash of the cell: most end
    /// points lie in a cell a beam of the same or the previous raster row
    /// ended in, found here without a look-up in `cells`.
    recent: Vec<u64>,
    /// The centres of the cells, in the order first met.
    centres: Vec<Point3>,
}

impl DiscreteScan {
    /// Fills the scan's end points: the centre of each finest cell some end
    /// point lies in, once, in the order the cells are first met (hits,
    /// then the no-return beams), to be inserted as hits
    /// ([`RayUpdater::find_cells`](super::RayUpdater::find_cells), which
    /// cuts those beyond the maximum range as OctoMap does).
    ///
    /// A no-return beam enters as its
    /// [`no_return_point`](super::no_return_point), as `--export-rays`
    /// hands it to OctoMap.
    /// OctoMap keys the `float` points it is given and casts to the `float`
    /// centres of their cells ([`Octree::key`], `float::centre`): so here.
    /// A point outside the tree's cube is left out (OctoMap's unchecked key
    /// would wrap around).
    pub fn fill(
        &mut self,
        tree: &Octree,
        origin: &Point3,
        (hits, misses): (&[Point3], &[Vector3]),
        max_range: f64,
    ) -> &[Point3] {
        self.cells.clear();
        self.centres.clear();
        self.recent.clear();
        self.recent.resize(RECENT_SLOTS, u64::MAX);
        let far = misses
            .iter()
            .map(|d| super::no_return_point(origin, d, max_range));
        for point in hits.iter().copied().chain(far) {
            let Some(key) = tree.key(&float::point(&point)) else {
                continue;
            };
            let packed = key.packed();
            let slot = &mut self.recent[recent_slot(packed)];
            if *slot == packed {
                continue;
            }
            *slot = packed;
            if self.cells.insert(packed) {
                let centre = key.0.map(|k| float::centre(k, tree.resolution()));
                self.centres.push(float::point(&Point3::from(centre)));
            }
        }
        &self.centres
    }
}

/// Slots of [`DiscreteScan::recent`].
const RECENT_SLOTS: usize = 1 << 12;

/// The slot of a packed key in [`DiscreteScan::recent`] (Fibonacci hashing).
#[inline]
fn recent_slot(packed: u64) -> usize {
    (packed.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 52) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The end points of a scan from (0.01, 0.02, 0.03), maximum range 2.
    fn run(resolution: f64, hits: &[Point3], misses: &[Vector3]) -> Vec<Point3> {
        let mut scan = DiscreteScan::default();
        let origin = Point3::new(0.01, 0.02, 0.03);
        let tree = Octree::new(resolution);
        scan.fill(&tree, &origin, (hits, misses), 2.0).to_vec()
    }

    #[test]
    fn points_of_one_cell_become_its_centre_once() {
        let hits = [
            Point3::new(1.01, 0.51, -0.24),
            Point3::new(1.04, 0.54, -0.21),
            Point3::new(1.06, 0.51, -0.24),
            Point3::new(1.02, 0.52, -0.23),
        ];
        let centre = |k: [f64; 3]| Point3::from(k.map(|k| f64::from(((k + 0.5) * 0.05) as f32)));
        assert_eq!(
            run(0.05, &hits, &[]),
            [centre([20.0, 10.0, -5.0]), centre([21.0, 10.0, -5.0])]
        );
    }

    #[test]
    fn a_no_return_beam_enters_at_twice_the_maximum_range() {
        let direction = Vector3::new(0.0, 0.6, 0.8);
        // origin + 4 d = (0.01, 2.42, 3.23): cells 0, 24, 32.
        let centre = Point3::from([0.0, 24.0, 32.0].map(|k| f64::from(((k + 0.5) * 0.1) as f32)));
        assert_eq!(run(0.1, &[], &[direction]), [centre]);
    }

    #[test]
    fn points_are_keyed_as_floats() {
        // 0.25 − 1e-9 lies in cell 4 of 0.05 m, but its float is 0.25, in
        // cell 5: OctoMap, given the float, casts to cell 5's centre.
        let out = run(0.05, &[Point3::new(0.25 - 1e-9, 1.0, 1.0)], &[]);
        assert_eq!(out[0].x, f64::from(0.275f32));
    }

    #[test]
    fn points_outside_the_tree_are_left_out() {
        assert!(run(0.01, &[Point3::new(400.0, 0.0, 0.0)], &[]).is_empty());
    }
}
