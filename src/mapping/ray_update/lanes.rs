//! Four rays walked at once, one per lane of AVX2 vectors. Lane by lane
//! these are the scalar walk's comparisons and additions
//! ([`finish`](super::dense::finish)), so the same cells: a lane whose
//! axis is not taken adds `0.0` (exact) and its index adds 0. The axis is
//! chosen by masks, not branches: the scalar walk spends most of its time
//! on mispredicted axis choices, while here the four lanes' steps are one
//! short chain of compare, mask and add, and the only branches left are the
//! rare end of a lane's ray and the marks.
//! The rays' set-up (end point, end key, the DDA's first crossings and
//! spacings) is computed four at a time too, into a buffer before the walk:
//! a refill that called back into the set-up from the walk's loop made the
//! compiler keep the lanes' state on the stack.

use super::dense::{mark_lanes, DenseWalk, LaneWalks, Walk};
use super::{mark, Dda, RayEnd};
use crate::geometry::{Point3, Vector3};
use crate::mapping::octree::{Key, CENTER};
use std::arch::x86_64::*;
use std::sync::atomic::AtomicU64;

/// [`DenseWalk::begin_hits`], four rays at a time: the rays' ends as
/// [`RayEnd::of_hit`] finds them, then [`begin_four`]. Compiled for AVX2:
/// call it where the CPU has it.
#[target_feature(enable = "avx2")]
pub(super) fn begin_hits(dense: &DenseWalk, hits: &[Point3], walks: &mut Vec<Walk>) {
    let max_range = _mm256_set1_pd(f64::from(dense.max_range as f32));
    let origin = dense.float_origin;
    let mut four = hits.chunks_exact(4);
    for hits in &mut four {
        let (mut point, mut diff) = ([_mm256_setzero_pd(); 3], [_mm256_setzero_pd(); 3]);
        for a in 0..3 {
            point[a] = to_float(_mm256_setr_pd(
                hits[0][a], hits[1][a], hits[2][a], hits[3][a],
            ));
            diff[a] = to_float(_mm256_sub_pd(point[a], _mm256_set1_pd(origin[a])));
        }
        let within = _mm256_cmp_pd::<_CMP_LE_OQ>(float_norm(diff), max_range);
        if _mm256_movemask_pd(within) == 0b1111 {
            begin_four(dense, point, 0b1111, walks);
        } else {
            // Some beyond max range (rare): one by one.
            let ends = hits
                .iter()
                .map(|p| RayEnd::of_hit(&origin, p, dense.max_range));
            walks.extend(ends.filter_map(|end| dense.begin(&end)));
        }
    }
    let ends = four
        .remainder()
        .iter()
        .map(|p| RayEnd::of_hit(&origin, p, dense.max_range));
    walks.extend(ends.filter_map(|end| dense.begin(&end)));
}

/// [`DenseWalk::begin_misses`], four rays at a time: the rays' ends as
/// [`RayEnd::of_miss`] finds them (the point at twice the maximum range,
/// cut at it in `float`), then [`begin_four`]. Compiled for AVX2: call it
/// where the CPU has it.
#[target_feature(enable = "avx2")]
pub(super) fn begin_misses(dense: &DenseWalk, misses: &[Vector3], walks: &mut Vec<Walk>) {
    let twice = _mm256_set1_pd(2.0 * dense.max_range);
    let max_range = _mm256_set1_pd(f64::from(dense.max_range as f32));
    let origin = dense.float_origin;
    let mut four = misses.chunks_exact(4);
    for chunk in &mut four {
        let mut diff = [_mm256_setzero_pd(); 3];
        for a in 0..3 {
            let d = _mm256_setr_pd(chunk[0][a], chunk[1][a], chunk[2][a], chunk[3][a]);
            let far = _mm256_add_pd(_mm256_set1_pd(dense.origin[a]), _mm256_mul_pd(d, twice));
            diff[a] = to_float(_mm256_sub_pd(to_float(far), _mm256_set1_pd(origin[a])));
        }
        let norm = float_norm(diff);
        let beyond = _mm256_cmp_pd::<_CMP_GT_OQ>(norm, max_range);
        if _mm256_movemask_pd(beyond) != 0b1111 {
            // A maximum range of nearly nothing: one by one.
            let ends = chunk
                .iter()
                .map(|d| RayEnd::of_miss(&dense.origin, &origin, d, dense.max_range));
            walks.extend(ends.filter_map(|end| dense.begin(&end)));
            continue;
        }
        // OctoMap's cut: origin + (d / (float) |d|) · (float) max_range.
        let length = to_float(norm);
        let mut end = [_mm256_setzero_pd(); 3];
        for a in 0..3 {
            let direction = to_float(_mm256_div_pd(diff[a], length));
            let reach = to_float(_mm256_mul_pd(direction, max_range));
            end[a] = to_float(_mm256_add_pd(_mm256_set1_pd(origin[a]), reach));
        }
        begin_four(dense, end, 0, walks);
    }
    let ends = four
        .remainder()
        .iter()
        .map(|d| RayEnd::of_miss(&dense.origin, &origin, d, dense.max_range));
    walks.extend(ends.filter_map(|end| dense.begin(&end)));
}

/// `x` rounded to the nearest `float`, lane by lane, in `f64`. An
/// operation on `float`s computed in `f64` and rounded so is the `float`
/// operation's result: `f64` carries more than twice `float`'s precision
/// plus two bits, so the double rounding is exact for +, −, ×, ÷ and √
/// (Figueroa, 1995). This is how the lanes do OctoMap's `float` arithmetic.
#[target_feature(enable = "avx2")]
#[inline]
fn to_float(x: __m256d) -> __m256d {
    _mm256_cvtps_pd(_mm256_cvtpd_ps(x))
}

/// [`float::norm`](super::float::norm) lane by lane: the `float` sum of the
/// `float` squares, (x² + y²) + z², its root in `f64`.
#[target_feature(enable = "avx2")]
#[inline]
fn float_norm(v: [__m256d; 3]) -> __m256d {
    let squares = v.map(|d| to_float(_mm256_mul_pd(d, d)));
    let sum = to_float(_mm256_add_pd(
        to_float(_mm256_add_pd(squares[0], squares[1])),
        squares[2],
    ));
    _mm256_sqrt_pd(sum)
}

/// [`DenseWalk::begin`] of four rays ending at the `float` points `point`
/// (lanes; hits where bit `k` of `hit` is set): the end cells' keys
/// ([`Octree::key`](crate::mapping::octree::Octree::key)) and the walks' set-up ([`Dda::new`])
/// with the same operations lane by lane (a dozen divisions and a square
/// root per ray, four to an instruction here).
#[target_feature(enable = "avx2")]
#[inline]
fn begin_four(dense: &DenseWalk, point: [__m256d; 3], hit: i32, walks: &mut Vec<Walk>) {
    let resolution = dense.tree.resolution();
    let res = _mm256_set1_pd(resolution);
    // OctoMap's `resolution_factor`, as `Octree::key` computes it.
    let factor = _mm256_set1_pd(1.0 / resolution);
    // OctoMap's half cell, a `float`.
    let half = f64::from((resolution * 0.5) as f32);
    let origin = dense.float_origin;
    let (sign, zero, none) = (
        _mm256_set1_pd(-0.0),
        _mm256_setzero_pd(),
        _mm256_set1_pd(f64::MAX),
    );
    // Lane by lane, per axis: the end cell's key, floor(p · factor) +
    // CENTER where |p · factor| < 1e9 and the key fits 16 bits (else the
    // ray is not walked); the walk's steps, its first crossing (of the
    // origin cell's centre ± the half cell, as `Dda::new` computes it) and
    // the crossings' spacing.
    let mut inside = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    let (mut key, mut diff) = ([[0.0; 4]; 3], [zero; 3]);
    for a in 0..3 {
        let v = _mm256_mul_pd(point[a], factor);
        let near = _mm256_cmp_pd::<_CMP_LT_OQ>(_mm256_andnot_pd(sign, v), _mm256_set1_pd(1e9));
        let k = _mm256_add_pd(_mm256_floor_pd(v), _mm256_set1_pd(CENTER as f64));
        let fits = _mm256_and_pd(
            _mm256_cmp_pd::<_CMP_GE_OQ>(k, zero),
            _mm256_cmp_pd::<_CMP_LT_OQ>(k, _mm256_set1_pd(65536.0)),
        );
        inside = _mm256_and_pd(inside, _mm256_and_pd(near, fits));
        key[a] = to_lanes(k);
        diff[a] = to_float(_mm256_sub_pd(point[a], _mm256_set1_pd(origin[a])));
    }
    let inside = _mm256_movemask_pd(inside);
    let length = to_float(float_norm(diff));
    let (mut t_max, mut t_delta) = ([[0.0; 4]; 3], [[0.0; 4]; 3]);
    let (mut forward, mut backward) = ([0; 3], [0; 3]);
    for a in 0..3 {
        let dir = to_float(_mm256_div_pd(diff[a], length));
        let ahead = _mm256_cmp_pd::<_CMP_GT_OQ>(dir, zero);
        let behind = _mm256_cmp_pd::<_CMP_LT_OQ>(dir, zero);
        let moves = _mm256_or_pd(ahead, behind);
        let centre = super::float::centre(dense.start_key.0[a], resolution);
        let border = _mm256_blendv_pd(
            _mm256_set1_pd(centre + -half),
            _mm256_set1_pd(centre + half),
            ahead,
        );
        let first = _mm256_div_pd(_mm256_sub_pd(border, _mm256_set1_pd(origin[a])), dir);
        let spacing = _mm256_div_pd(res, _mm256_andnot_pd(sign, dir));
        t_max[a] = to_lanes(_mm256_blendv_pd(none, first, moves));
        t_delta[a] = to_lanes(_mm256_blendv_pd(none, spacing, moves));
        forward[a] = _mm256_movemask_pd(ahead);
        backward[a] = _mm256_movemask_pd(behind);
    }
    let length = to_lanes(length);
    for lane in 0..4 {
        if inside & 1 << lane == 0 {
            continue;
        }
        let key = Key([0, 1, 2].map(|a| key[a][lane] as u16));
        let stop = dense.free.index(&key);
        if hit & 1 << lane != 0 {
            mark(&dense.occupied.bits, stop);
        }
        let dda = Dda {
            length: length[lane],
            step: [0, 1, 2].map(|a| (forward[a] >> lane & 1) - (backward[a] >> lane & 1)),
            t_max: [0, 1, 2].map(|a| t_max[a][lane]),
            t_delta: [0, 1, 2].map(|a| t_delta[a][lane]),
        };
        walks.extend(dense.walk(&dda, stop));
    }
}

/// The lanes of `v`.
#[target_feature(enable = "avx2")]
#[inline]
fn to_lanes(v: __m256d) -> [f64; 4] {
    // SAFETY: four f64 lanes, any bit pattern valid.
    unsafe { std::mem::transmute::<__m256d, [f64; 4]>(v) }
}

/// Four walks' state, lane `k` holding one ray (the fields of [`Walk`]).
#[derive(Clone, Copy)]
struct Lanes {
    tx: __m256d,
    ty: __m256d,
    tz: __m256d,
    dx: __m256d,
    dy: __m256d,
    dz: __m256d,
    length: __m256d,
    ix: __m256i,
    iy: __m256i,
    iz: __m256i,
    index: __m256i,
    stop: __m256i,
}

/// Marks the cells of every walk, as [`finish`](super::dense::finish)
/// does one by one, four at a time ([`mark_lanes`]). Compiled for AVX2:
/// call it where the CPU has it.
#[target_feature(enable = "avx2")]
pub(super) fn mark_rays(bits: &[AtomicU64], walks: &[Walk]) {
    // SAFETY: `Lanes` needs AVX2, which this function is compiled for and
    // runs with (a target-feature function is only called where the CPU
    // has its features).
    unsafe { mark_lanes::<Lanes>(bits, walks) }
}

impl LaneWalks for Lanes {
    const WIDTH: usize = 4;
    type Indices = [i64; 4];

    #[target_feature(enable = "avx2")]
    unsafe fn load(walks: &[Walk]) -> Self {
        let f = |field: fn(&Walk) -> f64| {
            _mm256_setr_pd(
                field(&walks[0]),
                field(&walks[1]),
                field(&walks[2]),
                field(&walks[3]),
            )
        };
        let i = |field: fn(&Walk) -> isize| {
            _mm256_setr_epi64x(
                field(&walks[0]) as i64,
                field(&walks[1]) as i64,
                field(&walks[2]) as i64,
                field(&walks[3]) as i64,
            )
        };
        Lanes {
            tx: f(|w| w.t_max[0]),
            ty: f(|w| w.t_max[1]),
            tz: f(|w| w.t_max[2]),
            dx: f(|w| w.t_delta[0]),
            dy: f(|w| w.t_delta[1]),
            dz: f(|w| w.t_delta[2]),
            length: f(|w| w.length),
            ix: i(|w| w.steps[0]),
            iy: i(|w| w.steps[1]),
            iz: i(|w| w.steps[2]),
            index: i(|w| w.index),
            stop: i(|w| w.stop),
        }
    }

    /// One step of every lane: x if before y and z, else z; y if before
    /// z, else z (OctoMap's choice, as in [`finish`](super::dense::finish)).
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn step(&mut self) {
        let x_before_y = _mm256_cmp_pd::<_CMP_LT_OQ>(self.tx, self.ty);
        let x_before_z = _mm256_cmp_pd::<_CMP_LT_OQ>(self.tx, self.tz);
        let y_before_z = _mm256_cmp_pd::<_CMP_LT_OQ>(self.ty, self.tz);
        let x = _mm256_and_pd(x_before_y, x_before_z);
        let y = _mm256_andnot_pd(x_before_y, y_before_z);
        let x_or_y = _mm256_or_pd(x, y);
        self.tx = _mm256_add_pd(self.tx, _mm256_and_pd(x, self.dx));
        self.ty = _mm256_add_pd(self.ty, _mm256_and_pd(y, self.dy));
        self.tz = _mm256_add_pd(self.tz, _mm256_andnot_pd(x_or_y, self.dz));
        let (x, y, x_or_y) = (
            _mm256_castpd_si256(x),
            _mm256_castpd_si256(y),
            _mm256_castpd_si256(x_or_y),
        );
        let step = _mm256_or_si256(
            _mm256_or_si256(_mm256_and_si256(x, self.ix), _mm256_and_si256(y, self.iy)),
            _mm256_andnot_si256(x_or_y, self.iz),
        );
        self.index = _mm256_add_epi64(self.index, step);
    }

    /// The lanes whose walk has ended (bit `k` for lane `k`): at the end
    /// cell, or past the segment's length on every axis.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn done(&self) -> u32 {
        let at_stop = _mm256_castsi256_pd(_mm256_cmpeq_epi64(self.index, self.stop));
        // All three past the length: the least is (no t is NaN).
        let least = _mm256_min_pd(_mm256_min_pd(self.tx, self.ty), self.tz);
        let past = _mm256_cmp_pd::<_CMP_GT_OQ>(least, self.length);
        _mm256_movemask_pd(_mm256_or_pd(at_stop, past)) as u32
    }

    /// The lanes' cells (bitmap indices).
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn indices(&self) -> [i64; 4] {
        [0, 1, 2, 3].map(|lane| lane_of(self.index, lane))
    }

    /// Puts `walk` in `lane`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn set(&mut self, lane: usize, walk: &Walk) {
        let mask = _mm256_cmpeq_epi64(
            _mm256_setr_epi64x(0, 1, 2, 3),
            _mm256_set1_epi64x(lane as i64),
        );
        let f = |old: __m256d, new: f64| {
            _mm256_blendv_pd(old, _mm256_set1_pd(new), _mm256_castsi256_pd(mask))
        };
        let i = |old: __m256i, new: isize| {
            _mm256_blendv_epi8(old, _mm256_set1_epi64x(new as i64), mask)
        };
        self.tx = f(self.tx, walk.t_max[0]);
        self.ty = f(self.ty, walk.t_max[1]);
        self.tz = f(self.tz, walk.t_max[2]);
        self.dx = f(self.dx, walk.t_delta[0]);
        self.dy = f(self.dy, walk.t_delta[1]);
        self.dz = f(self.dz, walk.t_delta[2]);
        self.length = f(self.length, walk.length);
        self.ix = i(self.ix, walk.steps[0]);
        self.iy = i(self.iy, walk.steps[1]);
        self.iz = i(self.iz, walk.steps[2]);
        self.index = i(self.index, walk.index);
        self.stop = i(self.stop, walk.stop);
    }

    /// The walk in `lane`, where it stands.
    #[target_feature(enable = "avx2")]
    unsafe fn get(&self, lane: usize) -> Walk {
        let f = |v: __m256d| f64::from_bits(lane_of(_mm256_castpd_si256(v), lane) as u64);
        let i = |v: __m256i| lane_of(v, lane) as isize;
        Walk {
            t_max: [f(self.tx), f(self.ty), f(self.tz)],
            t_delta: [f(self.dx), f(self.dy), f(self.dz)],
            length: f(self.length),
            steps: [i(self.ix), i(self.iy), i(self.iz)],
            index: i(self.index),
            stop: i(self.stop),
        }
    }
}

/// Lane `lane` of `v`, by value (an index into the vector's memory would
/// keep the lanes' state out of registers).
#[target_feature(enable = "avx2")]
#[inline]
fn lane_of(v: __m256i, lane: usize) -> i64 {
    match lane {
        0 => _mm256_extract_epi64::<0>(v),
        1 => _mm256_extract_epi64::<1>(v),
        2 => _mm256_extract_epi64::<2>(v),
        _ => _mm256_extract_epi64::<3>(v),
    }
}
