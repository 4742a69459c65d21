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
    walk_ray(tree, origin, end, |k| out.push(Key::unpack(k)))
}

/// The DDA behind [`ray_keys`]: calls `visit(key)` for each traversed
/// cell ([`Key::packed`]).
#[inline(always)]
fn walk_ray(tree: &Octree, origin: &Point3, end: &Point3, visit: impl FnMut(u64)) -> bool {
    let (Some(start), Some(stop)) = (tree.key(origin), tree.key(end)) else {
        return false;
    };
    walk_keys(tree, origin, start, end, stop, visit);
    true
}

/// [`walk_ray`] between ends whose keys (`start`, `stop`) are known.
#[inline(always)]
fn walk_keys(
    tree: &Octree,
    origin: &Point3,
    start: Key,
    end: &Point3,
    stop: Key,
    mut visit: impl FnMut(u64),
) {
    if start == stop {
        return;
    }
    visit(start.packed());
    let Dda {
        length,
        step,
        t_max,
        t_delta,
    } = Dda::new(tree, origin, start, end);
    // The walk's state in scalars (registers), one complete branch per
    // axis: indexing arrays by the axis taken would send every step
    // through memory (store-to-load stalls).
    let [mut x, mut y, mut z] = start.0;
    let [mut tx, mut ty, mut tz] = t_max;
    let [dx, dy, dz] = t_delta;
    let [sx, sy, sz] = step.map(|s| s as u16);
    let stop = stop.packed();
    loop {
        // OctoMap's choice: x if before y and z, else z; y if before z, else z.
        if tx < ty {
            if tx < tz {
                x = x.wrapping_add(sx);
                tx += dx;
            } else {
                z = z.wrapping_add(sz);
                tz += dz;
            }
        } else if ty < tz {
            y = y.wrapping_add(sy);
            ty += dy;
        } else {
            z = z.wrapping_add(sz);
            tz += dz;
        }
        let packed = x as u64 | (y as u64) << 16 | (z as u64) << 32;
        if packed == stop {
            return;
        }
        // Past the end point: numerical error; stop. (The smallest crossing
        // beyond `length`; no t is NaN, so no `f64::min` needed.)
        if (tx > length) & (ty > length) & (tz > length) {
            return;
        }
        visit(packed);
    }
}

/// The set-up of one ray's walk (OctoMap's `computeRayKeys`): the
/// segment's length, the step along each axis (±1, or 0 when the ray is
/// parallel to that axis's planes), the ray parameter of the first
/// crossing of each axis's cell border, and the parameter between two
/// crossings (`f64::MAX` on an axis without steps).
struct Dda {
    length: f64,
    step: [i32; 3],
    t_max: [f64; 3],
    t_delta: [f64; 3],
}

impl Dda {
    #[inline(always)]
    fn new(tree: &Octree, origin: &Point3, start: Key, end: &Point3) -> Self {
        let diff = end - origin;
        let length = diff.norm();
        let dir = diff / length;
        let res = tree.resolution();
        let mut step = [0i32; 3];
        let mut t_max = [f64::MAX; 3];
        let mut t_delta = [f64::MAX; 3];
        let centre = tree.center(&start, 16);
        for i in 0..3 {
            if dir[i] > 0.0 {
                step[i] = 1;
            } else if dir[i] < 0.0 {
                step[i] = -1;
            }
            if step[i] != 0 {
                let border = centre[i] + step[i] as f64 * res * 0.5;
                t_max[i] = (border - origin[i]) / dir[i];
                t_delta[i] = res / dir[i].abs();
            }
        }
        Dda {
            length,
            step,
            t_max,
            t_delta,
        }
    }
}

/// [`walk_keys`] on a dense set, setting each traversed cell's bit: the
/// same comparisons and additions, with the cell tracked by its bitmap
/// index alone (the end's cell is recognised by its index, which the one-
/// cell margin of the set's box keeps unique). No calls in the loop, so
/// its state stays in registers (a call would make every float register
/// caller-saved: the state would live on the stack); no keys built; the
/// set lists its cells afterwards ([`CellSet::list_marked_except`]).
struct DenseWalk<'a> {
    bits: &'a [AtomicU64],
    strides: [isize; 3],
}

impl DenseWalk<'_> {
    /// Marks the cells of the ray from the cell at `start` (bitmap index)
    /// to the one at `stop`, the latter excluded.
    #[inline(always)]
    fn mark_ray(&self, dda: &Dda, start: usize, stop: usize) {
        if start == stop {
            return;
        }
        mark(self.bits, start);
        let [ix, iy, iz]: [isize; 3] =
            std::array::from_fn(|a| self.strides[a] * dda.step[a] as isize);
        let [mut tx, mut ty, mut tz] = dda.t_max;
        let [dx, dy, dz] = dda.t_delta;
        let length = dda.length;
        let (mut index, stop) = (start as isize, stop as isize);
        loop {
            // As in `walk_keys`.
            index += if tx < ty {
                if tx < tz {
                    tx += dx;
                    ix
                } else {
                    tz += dz;
                    iz
                }
            } else if ty < tz {
                ty += dy;
                iy
            } else {
                tz += dz;
                iz
            };
            if index == stop {
                return;
            }
            if (tx > length) & (ty > length) & (tz > length) {
                return;
            }
            mark(self.bits, index as usize);
        }
    }
}

/// Sets bit `i` of a bitmap; true when it was not set (by any thread).
#[inline(always)]
fn mark(bits: &[AtomicU64], i: usize) -> bool {
    let (word, bit) = (&bits[i / 64], 1u64 << (i % 64));
    word.load(Relaxed) & bit == 0 && word.fetch_or(bit, Relaxed) & bit == 0
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

/// Bitmap words listed per parallel task.
const WORDS_PER_TASK: usize = 4096;

/// Largest bounding box (cells) kept as a bitmap: 2^27 bits, 16 MiB.
const DENSE_LIMIT: usize = 1 << 27;

impl CellSet {
    /// Empties the set for the box `min..=max`, a bitmap up to
    /// `dense_limit` cells.
    fn reset(&mut self, min: [u16; 3], max: [u16; 3], dense_limit: usize) {
        self.min = min;
        self.dims = std::array::from_fn(|a| (max[a] - min[a]) as usize + 1);
        let volume = self.dims.iter().product::<usize>();
        self.dense = volume <= dense_limit;
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
            mark(&self.bits, self.index(key))
        } else {
            self.hashed.insert(key.packed())
        };
        if new {
            self.codes.push(key.morton());
        }
    }

    /// Dense sets: lists the codes of the cells marked here but not in
    /// `except` (a set over the same box), in no order, after
    /// [`CellSet::mark`]s that did not list them.
    fn list_marked_except(&mut self, except: &CellSet) {
        debug_assert!(except.dense && except.min == self.min && except.dims == self.dims);
        let [nx, ny, _] = self.dims;
        let min = self.min;
        let found: Vec<Vec<u64>> = self
            .bits
            .par_chunks(WORDS_PER_TASK)
            .zip(except.bits.par_chunks(WORDS_PER_TASK))
            .enumerate()
            .map(|(task, (words, excepted))| {
                let mut codes = Vec::new();
                for (w, (word, excepted)) in words.iter().zip(excepted).enumerate() {
                    let mut bits = word.load(Relaxed) & !excepted.load(Relaxed);
                    let base = (task * WORDS_PER_TASK + w) * 64;
                    while bits != 0 {
                        let i = base + bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        let (x, rest) = (i % nx, i / nx);
                        let (y, z) = (rest % ny, rest / ny);
                        let offset = [x, y, z];
                        codes
                            .push(Key(std::array::from_fn(|a| min[a] + offset[a] as u16)).morton());
                    }
                }
                codes
            })
            .collect();
        self.codes.extend(found.into_iter().flatten());
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
    /// Largest box kept as a bitmap (tests: `Some(0)` for hash sets).
    dense_limit: Option<usize>,
    free: CellSet,
    occupied: CellSet,
    ends: Vec<RayEnd>,
}

/// Where one ray of a scan ends: the point, its key (none outside the
/// tree), and whether it is a measured hit (else a carve to max range).
struct RayEnd {
    point: Point3,
    key: Option<Key>,
    hit: bool,
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
        let end = |point: Point3, hit: bool| RayEnd {
            point,
            key: tree.key(&point),
            hit,
        };
        for p in hits {
            let d = p - origin;
            let n = d.norm();
            self.ends.push(if n <= max_range {
                end(*p, true)
            } else {
                end(origin + d * (max_range / n), false)
            });
        }
        self.ends
            .extend(misses.iter().map(|d| end(origin + d * max_range, false)));
        let Some(start) = tree.key(origin) else {
            return;
        };
        // The box of the scan's keys, one cell wider on every side: a walk
        // may end one cell past its end point's (numerical error).
        let (mut lo, mut hi) = (start.0, start.0);
        for k in self.ends.iter().filter_map(|e| e.key) {
            for a in 0..3 {
                lo[a] = lo[a].min(k.0[a]);
                hi[a] = hi[a].max(k.0[a]);
            }
        }
        let lo = lo.map(|v| v.saturating_sub(1));
        let hi = hi.map(|v| v.saturating_add(1));
        let dense_limit = self.dense_limit.unwrap_or(DENSE_LIMIT);
        self.free.reset(lo, hi, dense_limit);
        self.occupied.reset(lo, hi, dense_limit);
        // A ray is walked when both its ends lie in the tree (the origin does).
        if self.free.dense {
            // Rays in parallel chunks, each setting bits; the set is the
            // same whatever the thread count, and listed afterwards.
            let free = &self.free;
            let start_index = free.index(&start);
            self.ends.par_chunks(RAYS_PER_TASK).for_each(|chunk| {
                let walk = DenseWalk {
                    bits: &free.bits,
                    strides: std::array::from_fn(|axis| free.stride(axis)),
                };
                for e in chunk {
                    if let Some(stop) = e.key {
                        let dda = Dda::new(tree, origin, start, &e.point);
                        walk.mark_ray(&dda, start_index, free.index(&stop));
                    }
                }
            });
        } else {
            let free = &mut self.free;
            for e in &self.ends {
                if let Some(stop) = e.key {
                    walk_keys(tree, origin, start, &e.point, stop, |k| {
                        free.insert(&Key::unpack(k))
                    });
                }
            }
        }
        for e in &self.ends {
            if let (true, Some(k)) = (e.hit, e.key) {
                self.occupied.insert(&k);
            }
        }
        // Occupied wins; update in depth-first (Morton) order, one walk each.
        if self.free.dense {
            self.free.list_marked_except(&self.occupied);
        } else {
            let occupied = &self.occupied;
            self.free
                .codes
                .retain(|c| !occupied.contains(&Key::from_morton(*c)));
        }
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
mod tests;
