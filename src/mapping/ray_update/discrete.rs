//! OctoMap's discretized insertion (`insertPointCloud(..., discretize =
//! true)`, its `computeDiscreteUpdate`): a scan's points reduced to one per
//! finest cell, each moved to its cell's centre, before the usual update
//! (docs/octomap.md, "Discretized insertion").

use super::super::octree::CENTER;
use super::{RayEnd, ScanEnds};
use crate::geometry::{floor, Point3, Vector3};
use rustc_hash::FxHashSet;

/// One scan's rays as OctoMap's discretized insertion casts them, in
/// buffers kept for the next scan.
#[derive(Default)]
pub struct DiscreteScan {
    /// The end cells met so far ([`Key::packed`](super::Key::packed)).
    cells: FxHashSet<u64>,
    /// The cells met last, one per slot of a hash of the cell: most end
    /// points lie in a cell a beam of the same or the previous raster row
    /// ended in, found here without a look-up in `cells`.
    recent: Vec<u64>,
    /// The rays: to the centres within the maximum range (hits), and to
    /// the ends of those beyond it, cut at the maximum range.
    rays: Vec<RayEnd>,
}

impl DiscreteScan {
    /// Fills the scan's rays, and gives the origin they start from (the
    /// `float` origin OctoMap is given).
    ///
    /// Each finest cell some end point lies in gives one ray, to its centre,
    /// in the order the cells are first met (hits, then the no-return
    /// beams). A no-return beam along `direction` enters as its point at
    /// twice `max_range`, as `--export-rays` hands it to OctoMap. OctoMap
    /// keys the `float` points it is given, `floor(x · (1/res))`, casts to
    /// `float` centres, `(k − 2¹⁵ + ½) · res`, and cuts a ray longer than the
    /// maximum range in `float` arithmetic (`computeUpdate`): all three are
    /// done here on the same values, so the cells and the rays' ends are
    /// OctoMap's. A point outside the tree's cube is left out (OctoMap's key
    /// would wrap around).
    pub fn fill(
        &mut self,
        resolution: f64,
        origin: &Point3,
        (hits, misses): (&[Point3], &[Vector3]),
        max_range: f64,
    ) -> Point3 {
        self.cells.clear();
        self.rays.clear();
        self.recent.clear();
        self.recent.resize(RECENT_SLOTS, u64::MAX);
        let factor = 1.0 / resolution;
        let far = misses.iter().map(|d| origin + d * (2.0 * max_range));
        let origin_f32 = origin.map(|c| c as f32);
        let max_range = max_range as f32;
        for point in hits.iter().copied().chain(far) {
            let Some(key) = float_key(&point, factor) else {
                continue;
            };
            let packed = key[0] as u64 | (key[1] as u64) << 16 | (key[2] as u64) << 32;
            let slot = &mut self.recent[recent_slot(packed)];
            if *slot == packed {
                continue;
            }
            *slot = packed;
            if !self.cells.insert(packed) {
                continue;
            }
            let centre = key.map(|k| (((k as i64 - CENTER) as f64 + 0.5) * resolution) as f32);
            let (end, hit) = match cut(&origin_f32.into(), &centre, max_range) {
                None => (centre, true),
                Some(end) => (end, false),
            };
            let point = Point3::from(end.map(f64::from));
            self.rays.push(RayEnd { point, hit });
        }
        origin_f32.map(f64::from)
    }

    /// The rays filled last, to be walked as OctoMap walks them.
    pub fn ends(&self) -> ScanEnds<'_> {
        ScanEnds {
            hits: &[],
            misses: &[],
            float_rays: &self.rays,
        }
    }
}

/// Slots of [`DiscreteScan::recent`].
const RECENT_SLOTS: usize = 1 << 12;

/// The slot of a packed key in [`DiscreteScan::recent`] (Fibonacci hashing).
#[inline]
fn recent_slot(packed: u64) -> usize {
    (packed.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 52) as usize
}

/// OctoMap's `computeUpdate` for the `float` point `p` seen from `origin`:
/// `None` when `‖p − origin‖ ≤ max_range` (a hit), else the end of the ray
/// cut at `max_range`, `origin + (p − origin)/‖p − origin‖ · max_range`, in
/// OctoMap's `float` operations (its `norm` sums `float` squares and takes
/// the root in `double`).
fn cut(origin: &[f32; 3], p: &[f32; 3], max_range: f32) -> Option<[f32; 3]> {
    let d = [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]];
    let norm = f64::from(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if norm <= f64::from(max_range) {
        return None;
    }
    let length = norm as f32;
    Some(std::array::from_fn(|i| {
        origin[i] + d[i] / length * max_range
    }))
}

/// OctoMap's `coordToKey` of `point` as a `float` point: the finest key of
/// each coordinate, `floor(x · factor) + 2¹⁵`; `None` outside the tree.
#[inline]
fn float_key(point: &Point3, factor: f64) -> Option<[u16; 3]> {
    let mut key = [0u16; 3];
    for (out, &c) in key.iter_mut().zip(point.iter()) {
        let v = f64::from(c as f32) * factor;
        if v.is_nan() || v.abs() >= 1e9 {
            return None;
        }
        *out = u16::try_from(floor(v) + CENTER).ok()?;
    }
    Some(key)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rays of a scan from (0.01, 0.02, 0.03), maximum range 2.
    fn run(resolution: f64, hits: &[Point3], misses: &[Vector3]) -> Vec<RayEnd> {
        let mut scan = DiscreteScan::default();
        let origin = Point3::new(0.01, 0.02, 0.03);
        scan.fill(resolution, &origin, (hits, misses), 2.0);
        scan.ends().float_rays.to_vec()
    }

    #[test]
    fn points_of_one_cell_become_its_centre_once() {
        let hits = [
            Point3::new(1.01, 0.51, -0.24),
            Point3::new(1.04, 0.54, -0.21),
            Point3::new(1.06, 0.51, -0.24),
            Point3::new(1.02, 0.52, -0.23),
        ];
        let out = run(0.05, &hits, &[]);
        let centre = |v: f64| f64::from(v as f32);
        let hit = |point| RayEnd { point, hit: true };
        assert_eq!(
            out,
            [
                hit(Point3::new(centre(1.025), centre(0.525), centre(-0.225))),
                hit(Point3::new(centre(1.075), centre(0.525), centre(-0.225))),
            ]
        );
    }

    #[test]
    fn a_no_return_beam_enters_at_twice_the_maximum_range() {
        let direction = Vector3::new(0.0, 0.6, 0.8);
        let out = run(0.1, &[], &[direction]);
        // origin + 4 d = (0.01, 2.42, 3.23): cells 0, 24, 32, whose centre
        // lies beyond the maximum range (2): the ray to it, cut at 2.
        let centre = Point3::from([0.0, 24.0, 32.0].map(|k| f64::from(((k + 0.5) * 0.1) as f32)));
        let [RayEnd { point, hit: false }] = out[..] else {
            panic!("{out:?}");
        };
        let origin = Point3::new(0.01, 0.02, 0.03).map(|c| f64::from(c as f32));
        assert!(((point - origin).norm() - 2.0).abs() < 1e-6);
        let towards = (centre - origin).normalize();
        assert!((point - origin).normalize().dot(&towards) > 1.0 - 1e-12);
    }

    #[test]
    fn points_are_keyed_as_octomap_keys_their_float_coordinates() {
        // 0.25 − 1e-9 lies in cell 4 of 0.05 m, but its float is 0.25, in
        // cell 5: OctoMap, given the float, casts to cell 5's centre.
        let (resolution, x) = (0.05, 0.25 - 1e-9);
        assert_eq!(floor(x / resolution), 4);
        let out = run(resolution, &[Point3::new(x, 1.0, 1.0)], &[]);
        assert_eq!(out[0].point.x, f64::from(0.275f32));
    }

    #[test]
    fn a_ray_beyond_the_maximum_range_is_cut_in_octomaps_float_operations() {
        // OctoMap: `direction = (p − origin).normalized()` (each `float`
        // component over the `float` of the `double` norm), then `origin +
        // direction · (float) maxrange`, all in `float`.
        let origin = [0.013f32, -0.031, 0.257];
        let mut rounded_otherwise = 0;
        for i in 0..500 {
            let t = i as f32;
            let p = [1.5 + t * 0.037, -2.0 + t * 0.011, 3.0 - t * 0.005];
            let d: [f32; 3] = std::array::from_fn(|k| p[k] - origin[k]);
            let norm = f64::from(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let direction = d.map(|c| c / norm as f32);
            let octomap: [f32; 3] = std::array::from_fn(|k| origin[k] + direction[k] * 2.0);
            assert_eq!(cut(&origin, &p, 2.0), Some(octomap));
            let exact: [f32; 3] = std::array::from_fn(|k| {
                (f64::from(origin[k]) + f64::from(d[k]) / norm * 2.0) as f32
            });
            rounded_otherwise += usize::from(exact != octomap);
        }
        // The float operations matter: the end cells of such rays follow.
        assert!(rounded_otherwise > 50, "{rounded_otherwise}");
        assert_eq!(cut(&origin, &[1.0, 1.0, 1.0], 2.0), None);
    }

    #[test]
    fn points_outside_the_tree_are_left_out() {
        let out = run(0.01, &[Point3::new(400.0, 0.0, 0.0)], &[]);
        assert!(out.is_empty());
    }
}
