//! The standard OctoMap update, as a second modelling method: per scan, a 3-D
//! DDA (Amanatides & Woo) from the sensor origin to each end point marks the
//! traversed cells free and the end cell occupied; each cell gets at most one
//! update per scan and occupied wins; hit +0.85, miss −0.41, clamped to
//! [−2, 3.5] (docs/octomap.md, "The update rule"; OctoMap's `insertPointCloud`).

use super::octree::{Clamp, Key, Octree, LOG_ODDS_HIT, LOG_ODDS_MISS};
use crate::geometry::{Point3, Vector3};
use rayon::prelude::*;
use rustc_hash::FxHashSet;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// The cells a ray from `origin` to `end` traverses, the end cell excluded
/// (OctoMap's `computeRayKeys`). Appends to `out`; false if either end lies
/// outside the tree.
pub fn ray_keys(tree: &Octree, origin: &Point3, end: &Point3, out: &mut Vec<Key>) -> bool {
    walk_ray(tree, origin, end, &mut |k, _| out.push(Key::unpack(k)))
}

/// The DDA behind [`ray_keys`]: calls `visit(key, (axis, step))` for each
/// traversed cell ([`Key::packed`]: a key built in registers, not through
/// memory), with the move that reached it (`None` for the first).
#[inline]
fn walk_ray(tree: &Octree, origin: &Point3, end: &Point3, visit: &mut impl VisitCell) -> bool {
    let (Some(start), Some(stop)) = (tree.key(origin), tree.key(end)) else {
        return false;
    };
    if start == stop {
        return true;
    }
    visit.visit(start.packed(), None);
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
    // The walk's state in scalars (registers): indexing arrays by the axis
    // taken would send every step through memory (store-to-load stalls).
    let [mut x, mut y, mut z] = start.0;
    let [mut tx, mut ty, mut tz] = t_max;
    let [sx, sy, sz] = step.map(|s| s as u16);
    loop {
        // OctoMap's choice: x if before y and z, else z; y if before z, else z.
        let dim = if tx < ty {
            if tx < tz {
                x = x.wrapping_add(sx);
                tx += t_delta[0];
                0
            } else {
                z = z.wrapping_add(sz);
                tz += t_delta[2];
                2
            }
        } else if ty < tz {
            y = y.wrapping_add(sy);
            ty += t_delta[1];
            1
        } else {
            z = z.wrapping_add(sz);
            tz += t_delta[2];
            2
        };
        if [x, y, z] == stop.0 {
            return true;
        }
        // Past the end point: numerical error; stop. (The smallest crossing
        // beyond `length`; no t is NaN, so no `f64::min` needed.)
        if (tx > length) & (ty > length) & (tz > length) {
            return true;
        }
        let packed = x as u64 | (y as u64) << 16 | (z as u64) << 32;
        visit.visit(packed, Some((dim, step[dim])));
    }
}

/// What [`walk_ray`] calls for each cell: the packed key and the move that
/// reached it.
trait VisitCell {
    fn visit(&mut self, key: u64, moved: Option<(usize, i32)>);
}

impl<F: FnMut(u64, Option<(usize, i32)>)> VisitCell for F {
    #[inline]
    fn visit(&mut self, key: u64, moved: Option<(usize, i32)>) {
        self(key, moved)
    }
}

/// The ray update's visitor on a dense set: steps the bitmap index along
/// with the walk and lists the cells it is first to mark. Always inlined
/// into the walk, so the walk's state stays in registers.
struct MarkDense<'a> {
    set: &'a CellSet,
    strides: [isize; 3],
    index: isize,
    codes: &'a mut Vec<u64>,
}

impl VisitCell for MarkDense<'_> {
    #[inline(always)]
    fn visit(&mut self, key: u64, moved: Option<(usize, i32)>) {
        self.index = match moved {
            None => self.set.index(&Key::unpack(key)) as isize,
            Some((axis, step)) => self.index + self.strides[axis] * step as isize,
        };
        if self.set.mark(self.index as usize) {
            self.codes.push(Key::unpack(key).morton());
        }
    }
}

/// A set of cells of one scan: a bitmap over the scan's bounding box of keys
/// when it is small enough (the usual case), a hash set otherwise; either way
/// it also lists the Morton codes of its cells. The bitmap's words are atomic
/// so that rays can be walked in parallel.
#[derive(Default)]
struct CellSet {
    min: [u16; 3],
    dims: [usize; 3],
    bits: Vec<AtomicU64>,
    hashed: FxHashSet<u64>,
    dense: bool,
    codes: Vec<u64>,
}

/// Rays walked per parallel task.
const RAYS_PER_TASK: usize = 2048;

/// Largest bounding box (cells) kept as a bitmap: 2^27 bits, 16 MiB.
const DENSE_LIMIT: usize = 1 << 27;

impl CellSet {
    fn reset(&mut self, min: [u16; 3], max: [u16; 3]) {
        self.min = min;
        self.dims = std::array::from_fn(|a| (max[a] - min[a]) as usize + 1);
        let volume = self.dims.iter().product::<usize>();
        self.dense = volume <= DENSE_LIMIT;
        self.codes.clear();
        self.hashed.clear();
        if self.dense {
            self.bits.clear();
            self.bits
                .resize_with(volume.div_ceil(64), AtomicU64::default);
        }
    }

    #[inline]
    fn index(&self, key: &Key) -> usize {
        let [x, y, z] = std::array::from_fn(|a| (key.0[a] - self.min[a]) as usize);
        (z * self.dims[1] + y) * self.dims[0] + x
    }

    #[inline]
    fn insert(&mut self, key: &Key) {
        let new = if self.dense {
            self.mark(self.index(key))
        } else {
            self.hashed.insert(key.packed())
        };
        if new {
            self.codes.push(key.morton());
        }
    }

    /// Dense sets: sets bit `i`; true when it was not set (by any thread).
    #[inline]
    fn mark(&self, i: usize) -> bool {
        let (word, bit) = (&self.bits[i / 64], 1u64 << (i % 64));
        word.load(Relaxed) & bit == 0 && word.fetch_or(bit, Relaxed) & bit == 0
    }

    /// Bitmap index change of one step along `axis`.
    #[inline]
    fn stride(&self, axis: usize) -> isize {
        match axis {
            0 => 1,
            1 => self.dims[0] as isize,
            _ => (self.dims[0] * self.dims[1]) as isize,
        }
    }

    #[inline]
    fn contains(&self, key: &Key) -> bool {
        if self.dense {
            let i = self.index(key);
            self.bits[i / 64].load(Relaxed) & (1u64 << (i % 64)) != 0
        } else {
            self.hashed.contains(&key.packed())
        }
    }
}

/// OctoMap's per-scan cell update: `hit` (log-odds) where a beam ended,
/// `miss` where it passed (OctoMap's `setProbHit` / `setProbMiss`), then the
/// map-level `clamp` (`setClampingThresMin` / `Max`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UpdateRule {
    /// Added to the end cell of a returning beam (OctoMap: `logodds(0.7)`).
    pub hit: f32,
    /// Added to every cell a beam traverses (OctoMap: `logodds(0.4)`).
    pub miss: f32,
    /// The bounds every update is clamped to.
    pub clamp: Clamp,
}

impl UpdateRule {
    /// OctoMap's defaults, bit-exact.
    pub const OCTOMAP: UpdateRule = UpdateRule {
        hit: LOG_ODDS_HIT,
        miss: LOG_ODDS_MISS,
        clamp: Clamp::OCTOMAP,
    };
}

impl Default for UpdateRule {
    fn default() -> Self {
        Self::OCTOMAP
    }
}

/// Reusable buffers of the ray update (no allocation per scan once warm).
#[derive(Default)]
pub struct RayUpdater {
    rule: UpdateRule,
    free: CellSet,
    occupied: CellSet,
    ends: Vec<(Point3, bool)>,
}

impl RayUpdater {
    /// An updater applying `rule` ([`RayUpdater::default`]: OctoMap's).
    pub fn new(rule: UpdateRule) -> Self {
        Self {
            rule,
            ..Self::default()
        }
    }

    /// Inserts one scan: `hits` are measured end points; `misses` are the
    /// directions (unit) of beams that returned nothing, which carve free
    /// space up to `max_range`. Hits farther than `max_range` are truncated
    /// and only carve, as OctoMap does. [`RayUpdater::find_cells`] then
    /// [`RayUpdater::apply`].
    pub fn insert_scan(
        &mut self,
        tree: &mut Octree,
        origin: &Point3,
        hits: &[Point3],
        misses: &[Vector3],
        max_range: f64,
    ) {
        self.find_cells(tree, origin, hits, misses, max_range);
        self.apply(tree);
    }

    /// The first half of [`RayUpdater::insert_scan`]: finds the scan's free
    /// and occupied cells (rays walked in parallel), reading only the
    /// geometry of `tree` (its resolution), so a pipeline can find the next
    /// scan's cells while this scan's are applied.
    pub fn find_cells(
        &mut self,
        tree: &Octree,
        origin: &Point3,
        hits: &[Point3],
        misses: &[Vector3],
        max_range: f64,
    ) {
        // Nothing of the previous scan may be applied again.
        self.free.codes.clear();
        self.occupied.codes.clear();
        self.ends.clear();
        for p in hits {
            let d = p - origin;
            let n = d.norm();
            if n <= max_range {
                self.ends.push((*p, true));
            } else {
                self.ends.push((origin + d * (max_range / n), false));
            }
        }
        self.ends
            .extend(misses.iter().map(|d| (origin + d * max_range, false)));
        let Some(start) = tree.key(origin) else {
            return;
        };
        let (mut lo, mut hi) = (start.0, start.0);
        for (p, _) in &self.ends {
            if let Some(k) = tree.key(p) {
                for a in 0..3 {
                    lo[a] = lo[a].min(k.0[a]);
                    hi[a] = hi[a].max(k.0[a]);
                }
            }
        }
        self.free.reset(lo, hi);
        self.occupied.reset(lo, hi);
        let strides = [
            self.free.stride(0),
            self.free.stride(1),
            self.free.stride(2),
        ];
        if self.free.dense {
            // Rays in parallel chunks; a cell's code goes to the chunk that
            // set its bit first, so the set (and its sorted list) is the same
            // whatever the thread count.
            let free = &self.free;
            let found: Vec<Vec<u64>> = self
                .ends
                .par_chunks(RAYS_PER_TASK)
                .map(|chunk| {
                    let mut codes = Vec::new();
                    let mut visitor = MarkDense {
                        set: free,
                        strides,
                        index: 0,
                        codes: &mut codes,
                    };
                    for (end, _) in chunk {
                        walk_ray(tree, origin, end, &mut visitor);
                    }
                    codes
                })
                .collect();
            self.free.codes.extend(found.into_iter().flatten());
        } else {
            for (end, _) in &self.ends {
                let free = &mut self.free;
                walk_ray(tree, origin, end, &mut |k, _| free.insert(&Key::unpack(k)));
            }
        }
        // A ray is walked when both its ends lie in the tree (the origin does).
        for (end, hit) in &self.ends {
            if *hit {
                if let Some(k) = tree.key(end) {
                    self.occupied.insert(&k);
                }
            }
        }
        // Occupied wins; update in depth-first (Morton) order, one walk each.
        let occupied = &self.occupied;
        self.free
            .codes
            .retain(|c| !occupied.contains(&Key::from_morton(*c)));
        self.free.codes.par_sort_unstable();
        self.occupied.codes.sort_unstable();
    }

    /// The second half of [`RayUpdater::insert_scan`]: the cells found by
    /// the last [`RayUpdater::find_cells`] updated, free then occupied.
    pub fn apply(&self, tree: &mut Octree) {
        let rule = self.rule;
        tree.update_sorted(&self.free.codes, rule.miss, rule.clamp);
        tree.update_sorted(&self.occupied.codes, rule.hit, rule.clamp);
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

    #[test]
    fn a_custom_rule_sets_the_steps_and_the_clamp() {
        let rule = UpdateRule {
            hit: 0.25,
            miss: -0.125,
            clamp: Clamp {
                min: -0.2,
                max: 0.375,
            },
        };
        let mut tree = Octree::new(0.1);
        let origin = Point3::new(0.05, 0.05, 0.05);
        let hits = [Point3::new(0.55, 0.05, 0.05)];
        let mut updater = RayUpdater::new(rule);
        let at = |tree: &Octree, x: f64| tree.value_at(&Point3::new(x, 0.05, 0.05));
        updater.insert_scan(&mut tree, &origin, &hits, &[], 1.0);
        assert_eq!(at(&tree, 0.25), Some(-0.125));
        assert_eq!(at(&tree, 0.55), Some(0.25));
        updater.insert_scan(&mut tree, &origin, &hits, &[], 1.0);
        assert_eq!(at(&tree, 0.25), Some(-0.2), "clamped below");
        assert_eq!(at(&tree, 0.55), Some(0.375), "clamped above");
    }
}
