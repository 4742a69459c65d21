//! The standard OctoMap update, as a second modelling method: per scan, a 3-D
//! DDA (Amanatides & Woo) from the sensor origin to each end point marks the
//! traversed cells free and the end cell occupied; each cell gets at most one
//! update per scan and occupied wins; hit +0.85, miss −0.41, clamped to
//! [−2, 3.5] (OCTOMAP.md, "Update rule"; OctoMap's `insertPointCloud`).

use super::octree::{Clamp, Key, Octree, LOG_ODDS_HIT, LOG_ODDS_MISS};
use crate::geometry::{Point3, Vector3};
use rustc_hash::FxHashSet;

/// The cells a ray from `origin` to `end` traverses, the end cell excluded
/// (OctoMap's `computeRayKeys`). Appends to `out`; false if either end lies
/// outside the tree.
pub fn ray_keys(tree: &Octree, origin: &Point3, end: &Point3, out: &mut Vec<Key>) -> bool {
    let (Some(start), Some(stop)) = (tree.key(origin), tree.key(end)) else {
        return false;
    };
    if start == stop {
        return true;
    }
    out.push(start);
    let diff = end - origin;
    let length = diff.norm();
    let dir = diff / length;
    let res = tree.resolution();
    let mut step = [0i32; 3];
    let mut t_max = [f64::MAX; 3];
    let mut t_delta = [f64::MAX; 3];
    for i in 0..3 {
        if dir[i] > 0.0 {
            step[i] = 1;
        } else if dir[i] < 0.0 {
            step[i] = -1;
        }
        if step[i] != 0 {
            let border = tree.center(&start, 16)[i] + step[i] as f64 * res * 0.5;
            t_max[i] = (border - origin[i]) / dir[i];
            t_delta[i] = res / dir[i].abs();
        }
    }
    let mut current = start.0;
    loop {
        let dim = if t_max[0] < t_max[1] {
            if t_max[0] < t_max[2] {
                0
            } else {
                2
            }
        } else if t_max[1] < t_max[2] {
            1
        } else {
            2
        };
        current[dim] = (current[dim] as i32 + step[dim]) as u16;
        t_max[dim] += t_delta[dim];
        if current == stop.0 {
            return true;
        }
        // Past the end point: numerical error; stop.
        if t_max[0].min(t_max[1]).min(t_max[2]) > length {
            return true;
        }
        out.push(Key(current));
    }
}

/// Reusable buffers of the ray update (no allocation per scan once warm).
#[derive(Default)]
pub struct RayUpdater {
    free: FxHashSet<u64>,
    occupied: FxHashSet<u64>,
    ray: Vec<Key>,
    order: Vec<u64>,
}

impl RayUpdater {
    /// Inserts one scan: `hits` are measured end points; `misses` are the
    /// directions (unit) of beams that returned nothing, which carve free
    /// space up to `max_range`. Hits farther than `max_range` are truncated
    /// and only carve, as OctoMap does.
    pub fn insert_scan(
        &mut self,
        tree: &mut Octree,
        origin: &Point3,
        hits: &[Point3],
        misses: &[Vector3],
        max_range: f64,
    ) {
        self.free.clear();
        self.occupied.clear();
        for p in hits {
            let d = p - origin;
            if d.norm() <= max_range {
                self.ray.clear();
                if ray_keys(tree, origin, p, &mut self.ray) {
                    self.free.extend(self.ray.iter().map(Key::packed));
                    if let Some(k) = tree.key(p) {
                        self.occupied.insert(k.packed());
                    }
                }
            } else {
                self.carve(tree, origin, &(origin + d * (max_range / d.norm())));
            }
        }
        for dir in misses {
            self.carve(tree, origin, &(origin + dir * max_range));
        }
        // Update in key order: deterministic, and neighbouring cells share a path.
        self.order.clear();
        self.order
            .extend(self.free.iter().filter(|k| !self.occupied.contains(k)));
        self.order.sort_unstable();
        for k in &self.order {
            tree.update(&Key::unpack(*k), LOG_ODDS_MISS, Clamp::OCTOMAP);
        }
        self.order.clear();
        self.order.extend(self.occupied.iter());
        self.order.sort_unstable();
        for k in &self.order {
            tree.update(&Key::unpack(*k), LOG_ODDS_HIT, Clamp::OCTOMAP);
        }
    }

    fn carve(&mut self, tree: &Octree, origin: &Point3, end: &Point3) {
        self.ray.clear();
        if ray_keys(tree, origin, end, &mut self.ray) {
            self.free.extend(self.ray.iter().map(Key::packed));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_ray_visits_consecutive_cells() {
        let tree = Octree::new(0.1);
        let mut keys = Vec::new();
        assert!(ray_keys(
            &tree,
            &Point3::new(0.05, 0.05, 0.05),
            &Point3::new(0.95, 0.05, 0.05),
            &mut keys
        ));
        let xs: Vec<u16> = keys.iter().map(|k| k.0[0]).collect();
        assert_eq!(xs, (32768..32777).collect::<Vec<_>>());
        assert!(keys.iter().all(|k| k.0[1] == 32768 && k.0[2] == 32768));
    }

    #[test]
    fn diagonal_ray_is_face_connected_and_reaches_the_end() {
        let tree = Octree::new(0.05);
        let origin = Point3::new(0.013, -0.02, 0.031);
        let end = Point3::new(1.37, 0.61, -0.43);
        let mut keys = Vec::new();
        assert!(ray_keys(&tree, &origin, &end, &mut keys));
        assert_eq!(keys[0], tree.key(&origin).unwrap());
        let last = tree.key(&end).unwrap();
        let mut all = keys.clone();
        all.push(last);
        for pair in all.windows(2) {
            let steps: i32 = (0..3)
                .map(|a| (pair[0].0[a] as i32 - pair[1].0[a] as i32).abs())
                .sum();
            assert_eq!(steps, 1, "{pair:?}");
        }
        // Every cell the segment crosses lies on it (sampled densely).
        for i in 0..=10_000 {
            let p = origin + (end - origin) * (i as f64 / 10_000.0);
            let k = tree.key(&p).unwrap();
            assert!(all.contains(&k), "{p:?}");
        }
    }

    #[test]
    fn scan_marks_free_then_occupied_and_occupied_wins() {
        let mut tree = Octree::new(0.1);
        let origin = Point3::new(0.05, 0.05, 0.05);
        let hits = [Point3::new(0.55, 0.05, 0.05), Point3::new(0.35, 0.05, 0.05)];
        let mut updater = RayUpdater::default();
        updater.insert_scan(&mut tree, &origin, &hits, &[Vector3::y()], 1.0);
        let at = |x: f64, y: f64| tree.value_at(&Point3::new(x, y, 0.05));
        assert_eq!(at(0.05, 0.05), Some(LOG_ODDS_MISS));
        assert_eq!(at(0.25, 0.05), Some(LOG_ODDS_MISS));
        // Hit by one ray, traversed by the other: occupied, updated once.
        assert_eq!(at(0.35, 0.05), Some(LOG_ODDS_HIT));
        assert_eq!(at(0.55, 0.05), Some(LOG_ODDS_HIT));
        assert_eq!(at(0.65, 0.05), None);
        // The no-return beam carves up to max range only.
        assert_eq!(at(0.05, 0.95), Some(LOG_ODDS_MISS));
        assert_eq!(at(0.05, 1.15), None);
    }
}
