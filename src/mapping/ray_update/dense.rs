//! The ray update's walk on a dense set ([`CellSet`] bitmaps): what
//! [`walk_keys`](super::walk_keys) does, with the cell tracked by its bitmap
//! index alone (the end's cell is recognised by its index, which the one-
//! cell margin of the set's box keeps unique). No keys are built; the sets
//! list their cells afterwards ([`CellSet::list_marked`]).

use super::{float, mark, CellSet, Dda, RayEnd};
use crate::geometry::{Point3, Vector3};
use crate::mapping::octree::{Key, Octree};
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// What every ray of one scan shares: the grid, the origin and its cell,
/// the free and occupied bitmaps (one box), computed once per scan.
pub(super) struct DenseWalk<'a> {
    pub tree: &'a Octree,
    /// The scan's origin, as given (no-return beams' points start there).
    pub origin: Point3,
    /// The origin as the `float` point OctoMap holds: the rays start there.
    pub float_origin: Point3,
    pub max_range: f64,
    /// The origin's cell, as a bitmap index.
    pub start: usize,
    /// The origin's cell.
    pub start_key: Key,
    pub free: &'a CellSet,
    pub occupied: &'a CellSet,
    /// Bitmap index change of a step along each axis.
    pub strides: [isize; 3],
    /// Four rays at once in AVX2 vectors where the CPU has them
    /// ([`lanes`](super::lanes)); false: one at a time (tests compare).
    pub lanes: bool,
    /// With `lanes`, eight rays at once in AVX-512 vectors where the CPU
    /// has them ([`wide`](super::wide)); false: four (tests compare).
    pub wide: bool,
}

/// One ray's walk on a bitmap, at its start: the [`Dda`] with steps as
/// bitmap index changes and the cell as its index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Walk {
    pub t_max: [f64; 3],
    pub t_delta: [f64; 3],
    pub length: f64,
    /// Bitmap index change of a step along each axis (signed).
    pub steps: [isize; 3],
    pub index: isize,
    pub stop: isize,
}

/// Where a scan's rays start and how far they reach.
#[derive(Clone, Copy)]
pub struct ScanRays<'a> {
    /// The tree whose geometry (resolution) the rays are walked on.
    pub tree: &'a Octree,
    /// The sensor origin.
    pub origin: Point3,
    /// How far a ray reaches (OctoMap's maximum range).
    pub max_range: f64,
    /// The origin's cell.
    pub start: Key,
    /// Vectors where the CPU has them (false: one ray at a time).
    pub vectors: bool,
}

impl<'a> DenseWalk<'a> {
    /// The rays of `scan` on the bitmaps `free` and `occupied` of one box.
    pub fn new(scan: ScanRays<'a>, free: &'a CellSet, occupied: &'a CellSet) -> Self {
        DenseWalk {
            tree: scan.tree,
            origin: scan.origin,
            float_origin: float::point(&scan.origin),
            max_range: scan.max_range,
            start: free.index(&scan.start),
            start_key: scan.start,
            free,
            occupied,
            strides: std::array::from_fn(|axis| free.stride(axis)),
            lanes: scan.vectors,
            wide: scan.vectors,
        }
    }

    /// The ray of each of `hits` ([`RayEnd::of_hit`]) that ends in the
    /// tree: its end cell marked occupied if it is a hit, and its walk
    /// appended to `walks` (none when it ends in the origin's cell).
    pub fn begin_hits(&self, hits: &[Point3], walks: &mut Vec<Walk>) {
        #[cfg(target_arch = "x86_64")]
        if self.lanes && std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe { super::lanes::begin_hits(self, hits, walks) };
            return;
        }
        let ends = hits
            .iter()
            .map(|p| RayEnd::of_hit(&self.float_origin, p, self.max_range));
        walks.extend(ends.filter_map(|end| self.begin(&end)));
    }

    /// [`DenseWalk::begin_hits`] for beams without return
    /// ([`RayEnd::of_miss`]).
    pub fn begin_misses(&self, misses: &[Vector3], walks: &mut Vec<Walk>) {
        #[cfg(target_arch = "x86_64")]
        if self.lanes && std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe { super::lanes::begin_misses(self, misses, walks) };
            return;
        }
        let ends = misses
            .iter()
            .map(|d| RayEnd::of_miss(&self.origin, &self.float_origin, d, self.max_range));
        walks.extend(ends.filter_map(|end| self.begin(&end)));
    }

    /// [`DenseWalk::begin_hits`] of one ray.
    #[inline(always)]
    pub fn begin(&self, end: &RayEnd) -> Option<Walk> {
        let key = self.tree.key(&end.point)?;
        if end.hit {
            mark(&self.occupied.bits, self.occupied.index(&key));
        }
        let dda = Dda::new(
            self.tree.resolution(),
            &self.float_origin,
            &self.start_key,
            &end.point,
        );
        self.walk(&dda, self.free.index(&key))
    }

    /// The walk of `dda` from the origin's cell to the one at `stop`
    /// (bitmap index); none when the two are one cell (nothing to mark).
    #[inline(always)]
    pub fn walk(&self, dda: &Dda, stop: usize) -> Option<Walk> {
        if self.start == stop {
            return None;
        }
        Some(Walk {
            t_max: dda.t_max,
            t_delta: dda.t_delta,
            length: dda.length,
            steps: std::array::from_fn(|a| self.strides[a] * dda.step[a] as isize),
            index: self.start as isize,
            stop: stop as isize,
        })
    }

    /// Marks the free cells of every walk, the end cells excluded: the
    /// origin's cell, where every walk starts, once. Other threads may
    /// mark the same bitmap at the same time.
    pub fn mark_rays(&self, walks: &[Walk]) {
        mark_shared(&self.free.bits, self.start, walks, self.lanes, self.wide);
    }
}

/// [`DenseWalk::mark_rays`] on a bitmap no other thread touches meanwhile:
/// eight lanes (AVX-512) then read their eight words with one gather and
/// step on when every bit is already set (most steps, where rays crowd),
/// instead of testing them one by one. The same cells.
pub(super) fn mark_exclusive(
    bits: &mut [AtomicU64],
    start: usize,
    walks: &[Walk],
    lanes: bool,
    wide: bool,
) {
    #[cfg(target_arch = "x86_64")]
    if lanes && wide && !walks.is_empty() && std::arch::is_x86_feature_detected!("avx512f") {
        mark(bits, start);
        // SAFETY: the CPU has AVX-512F (checked just above); `bits` is
        // borrowed mutably, so no other thread reads or writes it.
        unsafe { super::wide::mark_rays_exclusive(bits, walks) };
        return;
    }
    mark_shared(bits, start, walks, lanes, wide);
}

/// [`DenseWalk::mark_rays`] of the walks from cell `start` on `bits`.
fn mark_shared(bits: &[AtomicU64], start: usize, walks: &[Walk], lanes: bool, wide: bool) {
    if walks.is_empty() {
        return;
    }
    mark(bits, start);
    #[cfg(target_arch = "x86_64")]
    {
        if lanes && wide && std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F (checked just above).
            unsafe { super::wide::mark_rays(bits, walks) };
            return;
        }
        if lanes && std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe { super::lanes::mark_rays(bits, walks) };
            return;
        }
    }
    for walk in walks {
        finish(bits, *walk);
    }
}

/// Marks the cells of `walk` after its current one, up to its end cell
/// (excluded): [`walk_keys`](super::walk_keys)'s comparisons and
/// additions. No calls in the loop, so its state stays in registers (a
/// call would make every float register caller-saved).
#[inline(always)]
pub(super) fn finish(bits: &[AtomicU64], walk: Walk) {
    let [ix, iy, iz] = walk.steps;
    let [mut tx, mut ty, mut tz] = walk.t_max;
    let [dx, dy, dz] = walk.t_delta;
    let Walk {
        length,
        mut index,
        stop,
        ..
    } = walk;
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
        mark(bits, index as usize);
    }
}

/// Walks held one per lane of vector registers (four with AVX2, eight with
/// AVX-512): the fields of [`Walk`] lane by lane, stepped together with the
/// scalar walk's comparisons and additions ([`finish`]). Every method needs
/// the CPU features its implementation is compiled for.
pub(super) trait LaneWalks: Sized {
    /// Walks held at once.
    const WIDTH: usize;
    /// The lanes' cells (bitmap indices), lane by lane.
    type Indices: IntoIterator<Item = i64> + AsRef<[i64]>;
    /// The first [`LaneWalks::WIDTH`] of `walks`, one per lane.
    unsafe fn load(walks: &[Walk]) -> Self;
    /// One step of every lane: x if before y and z, else z; y if before
    /// z, else z (OctoMap's choice, as in [`finish`]).
    unsafe fn step(&mut self);
    /// The lanes whose walk has ended (bit `k` for lane `k`): at the end
    /// cell, or past the segment's length on every axis.
    unsafe fn done(&self) -> u32;
    /// The lanes' cells.
    unsafe fn indices(&self) -> Self::Indices;
    /// Puts `walk` in `lane`.
    unsafe fn set(&mut self, lane: usize, walk: &Walk);
    /// The walk in `lane`, where it stands.
    unsafe fn get(&self, lane: usize) -> Walk;
}

/// Marks the cells of every walk, as [`finish`] does one by one, `L::WIDTH`
/// walks at a time: a lane whose walk ends takes the next.
///
/// # Safety
/// The CPU must have `L`'s features; inlined into a function compiled for
/// them.
#[inline(always)]
pub(super) unsafe fn mark_lanes<L: LaneWalks>(bits: &[AtomicU64], walks: &[Walk]) {
    if walks.len() < L::WIDTH {
        walks.iter().for_each(|w| finish(bits, *w));
        return;
    }
    let all = (1u32 << L::WIDTH) - 1;
    // SAFETY (every `L` call below): the caller's.
    let mut lanes = unsafe { L::load(walks) };
    let mut next = L::WIDTH;
    loop {
        unsafe { lanes.step() };
        let done = unsafe { lanes.done() };
        if done == 0 {
            for i in unsafe { lanes.indices() } {
                mark(bits, i as usize);
            }
            continue;
        }
        let index = unsafe { lanes.indices() };
        // A lane's ray ended: the lane takes the next ray.
        let mut live = 0u32;
        for (lane, &i) in index.as_ref().iter().enumerate() {
            if done & 1 << lane == 0 {
                mark(bits, i as usize);
                live |= 1 << lane;
            } else if let Some(walk) = walks.get(next) {
                unsafe { lanes.set(lane, walk) };
                next += 1;
                live |= 1 << lane;
            }
        }
        if live != all {
            // No rays left for the lanes that ended: the others finish
            // one by one.
            for lane in lanes_of(live) {
                finish(bits, unsafe { lanes.get(lane) });
            }
            return;
        }
    }
}

/// The lanes of `mask` (bit `k` for lane `k`), lowest first.
#[inline(always)]
pub(super) fn lanes_of(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask.wrapping_sub(1);
        (lane < 32).then_some(lane)
    })
}

/// Marks cell `i` of a bitmap no other thread accesses meanwhile: a plain
/// read and write instead of [`mark`]'s atomic read-modify-write.
#[inline(always)]
pub(super) fn mark_owned(bits: &[AtomicU64], i: usize) {
    let word = &bits[i / 64];
    word.store(word.load(Relaxed) | 1 << (i % 64), Relaxed);
}
