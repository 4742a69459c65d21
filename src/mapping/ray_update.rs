//! The standard OctoMap update, as a second modelling method: per scan, a 3-D
//! DDA (Amanatides & Woo) from the sensor origin to each end point marks the
//! traversed cells free and the end cell occupied; each cell gets at most one
//! update per scan and occupied wins; hit +0.85, miss −0.41, clamped to
//! [−2, 3.5] (docs/octomap.md, "The update rule"; OctoMap's `insertPointCloud`).
//! The rays are OctoMap's to the bit: keyed, cut and walked in its `float`
//! and `double` operations (`float`). [`DiscreteScan`] gives the rays of
//! its discretized insertion.

use super::octree::{Clamp, Key, Octree, LOG_ODDS_HIT, LOG_ODDS_MISS};
use crate::geometry::{Point3, Vector3};
use dense::{DenseWalk, ScanRays, Walk};
pub use discrete::DiscreteScan;
use rayon::prelude::*;
use rustc_hash::FxHashSet;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// The cells the segment from `origin` to `end` traverses, the end cell
/// excluded: OctoMap's `computeRayKeys` walk (its order between axes at a
/// tie) in `f64` on the exact points, the geometry the evaluation's truth
/// rays need (`eval::observable`). The ray update walks OctoMap's `float`
/// rays instead ([`RayUpdater::find_cells`]). Appends to `out`; false if
/// either end lies outside the tree.
pub fn ray_keys(tree: &Octree, origin: &Point3, end: &Point3, out: &mut Vec<Key>) -> bool {
    let (Some(start), Some(stop)) = (tree.key(origin), tree.key(end)) else {
        return false;
    };
    let dda = Dda::segment(tree.resolution(), origin, &tree.center(&start, 16), end);
    walk_keys(start, stop, &dda, |k| out.push(Key::unpack(k)));
    true
}

/// The point a beam without return along `direction` (unit) enters
/// OctoMap's `insertPointCloud` as, from the scan's `origin`: twice the
/// maximum range away, so that OctoMap cuts it to free space at that range
/// (`--export-rays` writes it; the ray update casts it).
pub fn no_return_point(origin: &Point3, direction: &Vector3, max_range: f64) -> Point3 {
    origin + direction * (2.0 * max_range)
}

/// The walk `dda` between cells whose keys (`start`, `stop`) are known:
/// calls `visit(key)` for each traversed cell ([`Key::packed`]).
#[inline(always)]
fn walk_keys(start: Key, stop: Key, dda: &Dda, mut visit: impl FnMut(u64)) {
    if start == stop {
        return;
    }
    visit(start.packed());
    let Dda {
        length,
        step,
        t_max,
        t_delta,
    } = *dda;
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
#[derive(Clone, Copy)]
struct Dda {
    length: f64,
    step: [i32; 3],
    t_max: [f64; 3],
    t_delta: [f64; 3],
}

impl Dda {
    /// The walk in `f64` from `origin`, in the cell whose centre is
    /// `centre`, to `end`, on a grid of cells of size `res` ([`ray_keys`]).
    fn segment(res: f64, origin: &Point3, centre: &Point3, end: &Point3) -> Self {
        let diff = end - origin;
        let length = diff.norm();
        let dir = diff / length;
        let border = |i: usize, step: i32| centre[i] + f64::from(step) * res * 0.5;
        Self::crossings(res, origin.coords.into(), dir.into(), length, border)
    }

    /// OctoMap's set-up (`computeRayKeys`) of the walk from `origin`, in
    /// the cell `start`, to `end`, both `float` points (their `f64`
    /// values), on a grid of cells of size `res`: the direction and length
    /// in `float` (its `norm` sums `float` squares and takes the root in
    /// `double`), the cell's borders and the crossings in `double`, each
    /// operation OctoMap's.
    #[inline(always)]
    fn new(res: f64, origin: &Point3, start: &Key, end: &Point3) -> Self {
        let (o, e) = (origin.map(|c| c as f32), end.map(|c| c as f32));
        let d = e - o;
        let length = float::norm(&d) as f32;
        let dir = d.map(|c| c / length);
        // keyToCoord, then the half cell as a `float`.
        let border = |i: usize, step: i32| {
            float::centre(start.0[i], res) + f64::from((f64::from(step) * res * 0.5) as f32)
        };
        let (o, dir) = (o.map(f64::from), dir.map(f64::from));
        Self::crossings(res, o.into(), dir.into(), f64::from(length), border)
    }

    /// The walk of `length` along the unit `dir` from `origin`: its step
    /// along each axis, the first crossing of the start cell's border there
    /// (`border(axis, step)`) and the spacing of the crossings, each in
    /// `f64` (OctoMap's `double`).
    #[inline(always)]
    fn crossings(
        res: f64,
        origin: [f64; 3],
        dir: [f64; 3],
        length: f64,
        border: impl Fn(usize, i32) -> f64,
    ) -> Self {
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
                t_max[i] = (border(i, step[i]) - origin[i]) / dir[i];
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

/// Sets bit `i` of a bitmap; true when it was not set (by any thread).
#[inline(always)]
fn mark(bits: &[AtomicU64], i: usize) -> bool {
    let (word, bit) = (&bits[i / 64], 1u64 << (i % 64));
    word.load(Relaxed) & bit == 0 && word.fetch_or(bit, Relaxed) & bit == 0
}

/// A set of cells of one scan: a bitmap over the scan's bounding box of keys
/// when it is small enough (the usual case), a hash set otherwise; either way
/// it also lists the Morton codes of its cells. The bitmap's words are atomic
/// so that rays can be walked in parallel; its rows (along x) are padded to
/// whole words, so that a word holds cells of one row.
#[derive(Default)]
struct CellSet {
    min: [u16; 3],
    dims: [usize; 3],
    /// Bits per row: `dims[0]` rounded up to a multiple of 64.
    row: usize,
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
    /// Empties the set for the box `min..=max` widened to whole 8³ blocks
    /// of keys (for [`CellSet::list_marked`]), a bitmap up to `dense_limit`
    /// cells.
    fn reset(&mut self, min: [u16; 3], max: [u16; 3], dense_limit: usize) {
        let (min, max) = (min.map(|v| v & !7), max.map(|v| v | 7));
        self.min = min;
        self.dims = std::array::from_fn(|a| (max[a] - min[a]) as usize + 1);
        self.row = self.dims[0].next_multiple_of(64);
        let volume = self.row * self.dims[1] * self.dims[2];
        self.dense = volume <= dense_limit;
        self.codes.clear();
        self.hashed.clear();
        if self.dense {
            self.bits.clear();
            self.bits.resize_with(volume / 64, AtomicU64::default);
        }
    }

    #[inline]
    fn index(&self, key: &Key) -> usize {
        let [x, y, z] = std::array::from_fn(|a| (key.0[a] - self.min[a]) as usize);
        (z * self.dims[1] + y) * self.row + x
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

    /// Bitmap index change of one step along `axis`.
    #[inline]
    fn stride(&self, axis: usize) -> isize {
        match axis {
            0 => 1,
            1 => self.row as isize,
            _ => (self.row * self.dims[1]) as isize,
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

/// A box of keys holding the origin's (`start`) and the end point's of
/// every ray ([`RayEnd`]) that ends in the tree, but for a sliver of a cell
/// on each side: the keys of the end points' least and greatest coordinates
/// (keys grow with coordinates), with each end taken in `f64` (the `float`
/// end lies within a thousandth of a cell of it, for any point the tree
/// holds: 2⁻²⁴ of 2¹⁵ cells); or, when one of those lies outside the tree,
/// the exact ends' keys one by one.
fn key_box(
    tree: &Octree,
    start: Key,
    origin: &Point3,
    (hits, misses): (&[Point3], &[Vector3]),
    max_range: f64,
) -> ([u16; 3], [u16; 3]) {
    // A hit within max range ends at itself: no square root.
    let square = max_range * max_range;
    let near_end_of_hit = |p: &Point3| {
        let d = p - origin;
        match d.norm_squared() <= square {
            true => *p,
            false => origin + d * (max_range / d.norm()),
        }
    };
    let near_ends = || {
        let hits = hits.par_iter().map(near_end_of_hit);
        hits.chain(misses.par_iter().map(|d| origin + d * max_range))
    };
    let float_origin = float::point(origin);
    let ends = || {
        let hits = hits
            .par_iter()
            .map(|p| RayEnd::of_hit(&float_origin, p, max_range).point);
        hits.chain(
            misses
                .par_iter()
                .map(|d| RayEnd::of_miss(origin, &float_origin, d, max_range).point),
        )
    };
    // (Least and greatest are exact whatever the order: the same box for
    // every thread count.)
    let none = || (Point3::from([f64::MAX; 3]), Point3::from([f64::MIN; 3]));
    let (least, greatest) = near_ends()
        .fold(none, |(l, g), e| (l.inf(&e), g.sup(&e)))
        .reduce(none, |(l, g), (m, h)| (l.inf(&m), g.sup(&h)));
    let (mut lo, mut hi) = (start.0, start.0);
    let mut widen = |k: Key| {
        for a in 0..3 {
            lo[a] = lo[a].min(k.0[a]);
            hi[a] = hi[a].max(k.0[a]);
        }
    };
    match (tree.key(&least), tree.key(&greatest)) {
        (Some(l), Some(g)) => {
            widen(l);
            widen(g);
        }
        _ => {
            let keys: Vec<Key> = ends().filter_map(|e| tree.key(&e)).collect();
            keys.into_iter().for_each(widen);
        }
    }
    (lo, hi)
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
    /// Walks rays one at a time even where the CPU could take four
    /// ([`DenseWalk`]; tests compare the two).
    one_at_a_time: bool,
    free: CellSet,
    occupied: CellSet,
    /// Walk every scan's rays on the calling thread ([`RayUpdater::walk_alone`]).
    alone: bool,
    /// The walks of one chunk of rays, when one thread walks them all.
    walks: Vec<Walk>,
}

/// Where one ray of a scan ends, as OctoMap's `computeUpdate` casts it:
/// the `float` point, and whether it is a measured hit (else the ray is cut
/// at the maximum range and only carves).
struct RayEnd {
    point: Point3,
    hit: bool,
}

impl RayEnd {
    /// The ray from the `float` point `origin` to the measured point `hit`
    /// (as a `float`): to it, or, when it lies beyond `max_range`, cut
    /// there ([`float::cut`]).
    #[inline(always)]
    fn of_hit(origin: &Point3, hit: &Point3, max_range: f64) -> Self {
        let point = float::point(hit);
        match float::cut(origin, &point, max_range) {
            None => RayEnd { point, hit: true },
            Some(point) => RayEnd { point, hit: false },
        }
    }

    /// The ray of a beam without return along `direction` (unit): its
    /// [`no_return_point`] from the scan's `origin`, cast from the `float`
    /// origin and so cut at `max_range` ([`RayEnd::of_hit`]).
    #[inline(always)]
    fn of_miss(
        origin: &Point3,
        float_origin: &Point3,
        direction: &Vector3,
        max_range: f64,
    ) -> Self {
        let far = no_return_point(origin, direction, max_range);
        RayEnd::of_hit(float_origin, &far, max_range)
    }
}

/// A scan's rays, to be walked in parallel: a run of hits or of misses.
enum Rays<'a> {
    Hits(&'a [Point3]),
    Misses(&'a [Vector3]),
}

impl RayUpdater {
    /// An updater applying `rule` ([`RayUpdater::default`]: OctoMap's).
    pub fn new(rule: UpdateRule) -> Self {
        Self {
            rule,
            ..Self::default()
        }
    }

    /// With `alone`, [`RayUpdater::find_cells`] walks a scan's rays on the
    /// calling thread instead of spreading them over the pool: for a
    /// pipeline whose other threads are busy with other scans. The walk
    /// then owns its bitmap and reads eight of its words at once (AVX-512);
    /// the cells are the same either way. (A pool of one thread always
    /// walks alone.)
    pub fn walk_alone(&mut self, alone: bool) {
        self.alone = alone;
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
    ///
    /// The rays are OctoMap's `insertPointCloud` of the scan as
    /// `--export-rays` writes it (`float` origin and points, a no-return
    /// beam as its point at twice `max_range`; docs/octomap.md): keyed,
    /// cut at the maximum range and walked in OctoMap's own `float` and
    /// `double` operations, so the cells are OctoMap's to the bit.
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
        let float_origin = float::point(origin);
        let Some(start) = tree.key(&float_origin) else {
            return;
        };
        // The box of the scan's keys, two cells wider on every side: one
        // for the sliver `key_box` may leave out, one as a walk may end one
        // cell past its end point's (numerical error).
        let (lo, hi) = key_box(tree, start, origin, (hits, misses), max_range);
        let lo = lo.map(|v| v.saturating_sub(2));
        let hi = hi.map(|v| v.saturating_add(2));
        let dense_limit = self.dense_limit.unwrap_or(DENSE_LIMIT);
        self.free.reset(lo, hi, dense_limit);
        self.occupied.reset(lo, hi, dense_limit);
        // A ray is walked when both its ends lie in the tree (the origin does).
        if self.free.dense {
            // Rays in chunks, each setting bits (free and occupied); the sets
            // are the same whatever the thread count, and listed afterwards.
            let scan = ScanRays {
                tree,
                origin: *origin,
                max_range,
                start,
                vectors: !self.one_at_a_time,
            };
            let begin = |dense: &DenseWalk, rays: Rays, walks: &mut Vec<Walk>| {
                walks.clear();
                match rays {
                    Rays::Hits(hits) => dense.begin_hits(hits, walks),
                    Rays::Misses(misses) => dense.begin_misses(misses, walks),
                }
            };
            if self.alone || rayon::current_num_threads() == 1 {
                // On this thread only: the free bitmap is this walk's
                // alone, which lets the walk read its words without
                // atomics ([`dense::mark_exclusive`]).
                let mut walks = std::mem::take(&mut self.walks);
                let hits = hits.chunks(RAYS_PER_TASK).map(Rays::Hits);
                let misses = misses.chunks(RAYS_PER_TASK).map(Rays::Misses);
                for rays in hits.chain(misses) {
                    let walk = DenseWalk::new(scan, &self.free, &self.occupied);
                    begin(&walk, rays, &mut walks);
                    let (start, lanes, wide) = (walk.start, walk.lanes, walk.wide);
                    dense::mark_exclusive(&mut self.free.bits, start, &walks, lanes, wide);
                }
                self.walks = walks;
            } else {
                // Chunks in parallel.
                let walk = DenseWalk::new(scan, &self.free, &self.occupied);
                let hits = hits.par_chunks(RAYS_PER_TASK).map(Rays::Hits);
                let misses = misses.par_chunks(RAYS_PER_TASK).map(Rays::Misses);
                let buffer = || Vec::with_capacity(RAYS_PER_TASK);
                hits.chain(misses).for_each_init(buffer, |walks, rays| {
                    begin(&walk, rays, walks);
                    walk.mark_rays(walks);
                });
            }
            // Occupied wins; in depth-first (Morton) order, so that `apply`
            // walks the tree once (listed here, so that a pipeline lists one
            // scan's cells while another's are applied).
            self.free.list_marked(&mut self.occupied);
        } else {
            let o = &float_origin;
            let hit_ends = hits.iter().map(|p| RayEnd::of_hit(o, p, max_range));
            let miss_ends = misses
                .iter()
                .map(|d| RayEnd::of_miss(origin, o, d, max_range));
            for e in hit_ends.chain(miss_ends) {
                let Some(stop) = tree.key(&e.point) else {
                    continue;
                };
                let dda = Dda::new(tree.resolution(), o, &start, &e.point);
                let free = &mut self.free;
                walk_keys(start, stop, &dda, |k| free.insert(&Key::unpack(k)));
                if e.hit {
                    self.occupied.insert(&stop);
                }
            }
            // Occupied wins.
            let occupied = &self.occupied;
            self.free
                .codes
                .retain(|c| !occupied.contains(&Key::from_morton(*c)));
            // In depth-first (Morton) order, as the bitmaps list them.
            radsort::sort(&mut self.free.codes);
            radsort::sort(&mut self.occupied.codes);
        }
    }

    /// The second half of [`RayUpdater::insert_scan`]: the cells found by
    /// the last [`RayUpdater::find_cells`] updated, free then occupied, each
    /// set in depth-first order (the tree walked once per set).
    pub fn apply(&self, tree: &mut Octree) {
        let rule = self.rule;
        tree.update_sorted(&self.free.codes, rule.miss, rule.clamp);
        tree.update_sorted(&self.occupied.codes, rule.hit, rule.clamp);
    }
}

mod dense;
mod discrete;
mod float;
#[cfg(target_arch = "x86_64")]
mod lanes;
mod listing;
#[cfg(test)]
mod tests;
#[cfg(target_arch = "x86_64")]
mod wide;
