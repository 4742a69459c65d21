//! Eight rays walked at once, one per lane of AVX-512 vectors: the walk of
//! [`lanes`](super::lanes) with twice the lanes. Lane by lane the scalar
//! walk's comparisons and additions ([`finish`](super::dense::finish)); a
//! lane whose axis is not taken is left as it is (masked additions), so the
//! same cells.

use super::dense::{finish, lanes_of, mark_lanes, mark_owned, LaneWalks, Walk};
use std::arch::x86_64::*;
use std::sync::atomic::AtomicU64;

/// Eight walks' state, lane `k` holding one ray (the fields of [`Walk`]).
#[derive(Clone, Copy)]
struct Lanes {
    tx: __m512d,
    ty: __m512d,
    tz: __m512d,
    dx: __m512d,
    dy: __m512d,
    dz: __m512d,
    length: __m512d,
    ix: __m512i,
    iy: __m512i,
    iz: __m512i,
    index: __m512i,
    stop: __m512i,
}

/// Marks the cells of every walk, as [`finish`] does one by one, eight at
/// a time ([`mark_lanes`]). Compiled for AVX-512F: call it where the CPU
/// has it.
#[target_feature(enable = "avx512f")]
pub(super) fn mark_rays(bits: &[AtomicU64], walks: &[Walk]) {
    // SAFETY: `Lanes` needs AVX-512F, which this function is compiled for
    // and runs with.
    unsafe { mark_lanes::<Lanes>(bits, walks) }
}

/// [`mark_rays`] on a bitmap this thread alone holds: each step reads its
/// eight words with one gather and marks only lanes whose bit is not set
/// ([`mark_owned`]); ended lanes take the next walks in the same branch,
/// taken on a few steps in ten where rays crowd. Compiled for AVX-512F:
/// call it where the CPU has it.
#[target_feature(enable = "avx512f")]
pub(super) fn mark_rays_exclusive(bits: &mut [AtomicU64], walks: &[Walk]) {
    let bits: &[AtomicU64] = bits;
    if walks.len() < Lanes::WIDTH {
        walks.iter().for_each(|w| finish(bits, *w));
        return;
    }
    const ALL: __mmask8 = 0xff;
    // SAFETY (every `Lanes` call below): the CPU has AVX-512F (the
    // caller's); `bits` was borrowed mutably, so no other thread accesses
    // it during the call.
    let mut lanes = unsafe { Lanes::load(walks) };
    let mut next = Lanes::WIDTH;
    loop {
        unsafe { lanes.step() };
        let live = lanes.live();
        let unset = unsafe { lanes.unset(bits, live) };
        if live == ALL && unset == 0 {
            continue;
        }
        let index = unsafe { lanes.indices() };
        for lane in lanes_of(u32::from(unset)) {
            mark_owned(bits, index[lane] as usize);
        }
        if live == ALL {
            continue;
        }
        // Ended lanes take the next walks.
        let mut going = ALL;
        for lane in lanes_of(u32::from(!live)) {
            if let Some(walk) = walks.get(next) {
                unsafe { lanes.set(lane, walk) };
                next += 1;
            } else {
                going &= !(1 << lane);
            }
        }
        if going != ALL {
            // No walks left for them: the others finish one by one.
            for lane in lanes_of(u32::from(going)) {
                finish(bits, unsafe { lanes.get(lane) });
            }
            return;
        }
    }
}

impl Lanes {
    /// The lanes whose walk goes on (bit `k` for lane `k`): not at the end
    /// cell, and not past the segment's length on every axis (the least t
    /// is not; unordered counts as not past, as in
    /// [`finish`](super::dense::finish)).
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn live(&self) -> __mmask8 {
        let before_stop = _mm512_cmpneq_epi64_mask(self.index, self.stop);
        let least = _mm512_min_pd(_mm512_min_pd(self.tx, self.ty), self.tz);
        _mm512_mask_cmp_pd_mask::<_CMP_NGT_UQ>(before_stop, least, self.length)
    }

    /// The lanes of `live` whose cell's bit in `bits` is not set, read with
    /// one masked gather; a lane whose index lies outside `bits` is not
    /// read and counts as not set (its mark then fails as the scalar
    /// walk's would).
    ///
    /// # Safety
    /// Besides AVX-512F, no other thread may access `bits` during the call
    /// (its words are read without atomics).
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn unset(&self, bits: &[AtomicU64], live: __mmask8) -> __mmask8 {
        let words = _mm512_srli_epi64::<6>(self.index);
        // Unsigned: a negative index is outside too.
        let inside = _mm512_cmplt_epu64_mask(words, _mm512_set1_epi64(bits.len() as i64));
        // SAFETY: only the lanes of `inside` are read, each an element of
        // `bits` (an `AtomicU64` has the layout of an `i64`); no other
        // thread accesses `bits` (the caller's), so a plain read is no
        // data race.
        let word = unsafe {
            _mm512_mask_i64gather_epi64::<8>(
                _mm512_setzero_si512(),
                inside,
                words,
                bits.as_ptr().cast::<i64>(),
            )
        };
        let bit_first =
            _mm512_srlv_epi64(word, _mm512_and_si512(self.index, _mm512_set1_epi64(63)));
        _mm512_mask_testn_epi64_mask(live, bit_first, _mm512_set1_epi64(1))
    }
}

impl LaneWalks for Lanes {
    const WIDTH: usize = 8;
    type Indices = [i64; 8];

    #[target_feature(enable = "avx512f")]
    unsafe fn load(walks: &[Walk]) -> Self {
        let f = |field: fn(&Walk) -> f64| {
            let v: [f64; 8] = std::array::from_fn(|k| field(&walks[k]));
            // SAFETY: eight f64 read from an array of eight.
            unsafe { _mm512_loadu_pd(v.as_ptr()) }
        };
        let i = |field: fn(&Walk) -> isize| {
            let v: [i64; 8] = std::array::from_fn(|k| field(&walks[k]) as i64);
            // SAFETY: eight i64 read from an array of eight.
            unsafe { _mm512_loadu_epi64(v.as_ptr()) }
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
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn step(&mut self) {
        let x_before_y = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(self.tx, self.ty);
        let x_before_z = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(self.tx, self.tz);
        let y_before_z = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(self.ty, self.tz);
        let x = x_before_y & x_before_z;
        let y = !x_before_y & y_before_z;
        let z = !(x | y);
        self.tx = _mm512_mask_add_pd(self.tx, x, self.tx, self.dx);
        self.ty = _mm512_mask_add_pd(self.ty, y, self.ty, self.dy);
        self.tz = _mm512_mask_add_pd(self.tz, z, self.tz, self.dz);
        let step = _mm512_mask_mov_epi64(_mm512_mask_mov_epi64(self.iz, y, self.iy), x, self.ix);
        self.index = _mm512_add_epi64(self.index, step);
    }

    /// The lanes whose walk has ended (bit `k` for lane `k`): those not
    /// [`Lanes::live`].
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn done(&self) -> u32 {
        u32::from(!self.live())
    }

    /// The lanes' cells (bitmap indices).
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn indices(&self) -> [i64; 8] {
        let mut out = [0i64; 8];
        // SAFETY: eight i64 written to an array of eight.
        unsafe { _mm512_storeu_epi64(out.as_mut_ptr(), self.index) };
        out
    }

    /// Puts `walk` in `lane`.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn set(&mut self, lane: usize, walk: &Walk) {
        let k: __mmask8 = 1 << lane;
        let f = |old: __m512d, new: f64| _mm512_mask_mov_pd(old, k, _mm512_set1_pd(new));
        let i =
            |old: __m512i, new: isize| _mm512_mask_mov_epi64(old, k, _mm512_set1_epi64(new as i64));
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
    #[target_feature(enable = "avx512f")]
    unsafe fn get(&self, lane: usize) -> Walk {
        let f = |v: __m512d| {
            let mut out = [0.0f64; 8];
            // SAFETY: eight f64 written to an array of eight.
            unsafe { _mm512_storeu_pd(out.as_mut_ptr(), v) };
            out[lane]
        };
        let i = |v: __m512i| {
            let mut out = [0i64; 8];
            // SAFETY: eight i64 written to an array of eight.
            unsafe { _mm512_storeu_epi64(out.as_mut_ptr(), v) };
            out[lane] as isize
        };
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
