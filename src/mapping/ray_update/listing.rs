//! A scan's bitmaps listed in depth-first (Morton) order without a sort.
//!
//! The bitmap's box is whole 8³ blocks of keys, aligned on multiples of 8
//! ([`CellSet::reset`]), so a cell's Morton code is its block's code followed
//! by the 9 bits of its place in the block. The non-empty blocks (a few
//! thousand a scan, against millions of cells at 1 cm) are sorted by code;
//! each block's cells then come out in order from its 64 bytes (8 rows × 8
//! planes of 8 cells), 2 × 2 × 2 sub-cube by sub-cube.

use super::CellSet;
use crate::mapping::octree::Key;
use rayon::prelude::*;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// Blocks listed per parallel task.
const BLOCKS_PER_TASK: usize = 256;

/// The sub-cube `(i, j, k)` (each 0–3: x, y, z in pairs of cells) at each
/// place of the Morton order of a block's 64 sub-cubes.
const SUB_CUBES: [[usize; 3]; 64] = {
    let mut table = [[0; 3]; 64];
    let mut s = 0;
    while s < 64 {
        table[s] = [
            (s & 1) | (s >> 2 & 2),
            (s >> 1 & 1) | (s >> 3 & 2),
            (s >> 2 & 1) | (s >> 4 & 2),
        ];
        s += 1;
    }
    table
};

/// A non-empty block: its Morton code and its place in the box (in blocks).
#[derive(Clone, Copy)]
struct Block {
    code: u64,
    at: [usize; 3],
}

impl CellSet {
    /// Dense sets marked by [`super::mark`] without listing (this one the
    /// free cells, `occupied` over the same box): lists the codes of both in
    /// Morton order, the free ones that are also occupied left out.
    pub(super) fn list_marked(&mut self, occupied: &mut CellSet) {
        debug_assert!(occupied.dense && occupied.min == self.min && occupied.dims == self.dims);
        debug_assert!(self.min.iter().all(|m| m % 8 == 0) && self.dims.iter().all(|d| d % 8 == 0));
        let mut blocks = self.blocks(occupied);
        blocks.sort_unstable_by_key(|b| b.code);
        let rows = Rows::of(self);
        let (free, taken) = (&self.bits, &occupied.bits);
        // Each task's cells counted first, so that every task writes its
        // codes in place: no buffer per task, no copy, and the lists keep
        // their memory from scan to scan.
        let tasks: Vec<&[Block]> = blocks.chunks(BLOCKS_PER_TASK).collect();
        let counts: Vec<[usize; 2]> = tasks
            .par_iter()
            .map(|blocks| {
                blocks.iter().fold([0, 0], |[f, o], block| {
                    let (free_bytes, occupied_bytes) = rows.block_bytes(block, free, taken);
                    [f + ones(&free_bytes), o + ones(&occupied_bytes)]
                })
            })
            .collect();
        let total = counts
            .iter()
            .fold([0, 0], |[f, o], [tf, to]| [f + tf, o + to]);
        let (free_codes, occupied_codes) = (&mut self.codes, &mut occupied.codes);
        free_codes.clear();
        occupied_codes.clear();
        free_codes.reserve(total[0]);
        occupied_codes.reserve(total[1]);
        let mut free_rest = &mut free_codes.spare_capacity_mut()[..total[0]];
        let mut occupied_rest = &mut occupied_codes.spare_capacity_mut()[..total[1]];
        let mut jobs = Vec::with_capacity(tasks.len());
        for (blocks, &[f, o]) in tasks.into_iter().zip(&counts) {
            let (free_out, rest) = std::mem::take(&mut free_rest).split_at_mut(f);
            free_rest = rest;
            let (occupied_out, rest) = std::mem::take(&mut occupied_rest).split_at_mut(o);
            occupied_rest = rest;
            jobs.push((blocks, free_out, occupied_out));
        }
        jobs.into_par_iter()
            .for_each(|(blocks, free_out, occupied_out)| {
                let (mut f, mut o) = (0, 0);
                for block in blocks {
                    let (free_bytes, occupied_bytes) = rows.block_bytes(block, free, taken);
                    emit(&free_bytes, block.code, free_out, &mut f);
                    emit(&occupied_bytes, block.code, occupied_out, &mut o);
                }
                // Every slot written (`emit` cannot write past the end).
                assert!(f == free_out.len() && o == occupied_out.len());
            });
        // SAFETY: the first `total` slots of each list's spare capacity were
        // handed out above as disjoint slices, and each task wrote every
        // slot of its own (asserted), so they are initialised.
        unsafe {
            free_codes.set_len(total[0]);
            occupied_codes.set_len(total[1]);
        }
    }

    /// The blocks holding a free or an occupied cell, in box order.
    fn blocks(&self, occupied: &CellSet) -> Vec<Block> {
        let rows = Rows::of(self);
        let [_, ny, nz] = self.dims.map(|d| d / 8);
        let (free, taken) = (&self.bits, &occupied.bits);
        (0..ny * nz)
            .into_par_iter()
            .flat_map_iter(|yz| {
                let (by, bz) = (yz % ny, yz / ny);
                (0..rows.words).flat_map(move |w| {
                    // The union of the block-row's 64 rows in this word
                    // (the rows' padding past the box is never marked).
                    let mut any = 0u64;
                    for z in 0..8 {
                        for y in 0..8 {
                            let word = rows.row_index(by, bz, y, z) * rows.words + w;
                            any |= free[word].load(Relaxed) | taken[word].load(Relaxed);
                        }
                    }
                    (0..8)
                        .filter(move |byte| any >> (8 * byte) & 0xff != 0)
                        .map(move |byte| w * 8 + byte)
                        .map(move |bx| Block {
                            code: block_code(self.min, [bx, by, bz]),
                            at: [bx, by, bz],
                        })
                })
            })
            .collect()
    }
}

/// The rows of a set's bitmap: what listing a block needs of its layout.
#[derive(Clone, Copy)]
struct Rows {
    /// Words per row of the box.
    words: usize,
    /// Rows per plane of the box (its cells along y).
    per_plane: usize,
}

impl Rows {
    fn of(set: &CellSet) -> Self {
        Rows {
            words: set.row / 64,
            per_plane: set.dims[1],
        }
    }

    /// Row `y` of plane `z` of the block row `(by, bz)`, as a row of the box.
    #[inline]
    fn row_index(self, by: usize, bz: usize, y: usize, z: usize) -> usize {
        (bz * 8 + z) * self.per_plane + by * 8 + y
    }

    /// A block's free cells (not occupied) and occupied cells, a byte (8
    /// cells along x) per row `y + 8 z`.
    #[inline]
    fn block_bytes(
        self,
        block: &Block,
        free: &[AtomicU64],
        taken: &[AtomicU64],
    ) -> ([u8; 64], [u8; 64]) {
        let [bx, by, bz] = block.at;
        let shift = 8 * (bx % 8);
        let (mut free_bytes, mut occupied_bytes) = ([0u8; 64], [0u8; 64]);
        for z in 0..8 {
            for y in 0..8 {
                let word = self.row_index(by, bz, y, z) * self.words + bx / 8;
                let occupied = (taken[word].load(Relaxed) >> shift) as u8;
                free_bytes[y + 8 * z] = (free[word].load(Relaxed) >> shift) as u8 & !occupied;
                occupied_bytes[y + 8 * z] = occupied;
            }
        }
        (free_bytes, occupied_bytes)
    }
}

/// The cells set in a block's bytes.
#[inline]
fn ones(bytes: &[u8; 64]) -> usize {
    bytes.iter().map(|b| b.count_ones() as usize).sum()
}

/// The Morton code of the block `at` (in blocks from `min`, a multiple of 8
/// on every axis), shifted to make room for the 9 bits of a cell in it.
fn block_code(min: [u16; 3], at: [usize; 3]) -> u64 {
    Key(std::array::from_fn(|a| min[a] / 8 + at[a] as u16)).morton() << 9
}

/// Writes the Morton codes of a block's set cells (`bytes`: bit `x` of byte
/// `y + 8 z`) to `out` from slot `at` on, in order, and moves `at` past
/// them; `base` is the block's code.
#[inline]
fn emit(bytes: &[u8; 64], base: u64, out: &mut [MaybeUninit<u64>], at: &mut usize) {
    for (s, &[i, j, k]) in SUB_CUBES.iter().enumerate() {
        // Two cells along x from each of the sub-cube's four rows: bit
        // x + 2 y + 4 z of the sub-cube, its Morton order.
        let pair = |y: usize, z: usize| (bytes[y + 8 * z] >> (2 * i)) & 3;
        let mut cells = pair(2 * j, 2 * k)
            | pair(2 * j + 1, 2 * k) << 2
            | pair(2 * j, 2 * k + 1) << 4
            | pair(2 * j + 1, 2 * k + 1) << 6;
        while cells != 0 {
            out[*at].write(base | (s as u64) << 3 | u64::from(cells.trailing_zeros()));
            *at += 1;
            cells &= cells - 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn sub_cubes_follow_the_morton_order() {
        for (s, &[i, j, k]) in SUB_CUBES.iter().enumerate() {
            assert_eq!(Key([i as u16, j as u16, k as u16]).morton(), s as u64);
        }
    }

    #[test]
    fn bitmaps_list_in_morton_order_with_occupied_winning() {
        // Boxes of every alignment, around the tree's centre (where every
        // bit of the keys changes) and away from it; sparse and dense.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        // The same sets from round to round, as a scan's follow another's:
        // their lists keep their memory, not their cells.
        let (mut free, mut occupied) = (CellSet::default(), CellSet::default());
        for round in 0..40 {
            let centre: u16 = if round % 2 == 0 { 32768 } else { 1000 };
            let lo: [u16; 3] = std::array::from_fn(|_| centre - rng.random_range(1..40));
            let hi: [u16; 3] = std::array::from_fn(|a| lo[a] + rng.random_range(0..70));
            free.reset(lo, hi, usize::MAX);
            occupied.reset(lo, hi, usize::MAX);
            let density = [0.001, 0.05, 0.6][round % 3];
            let (mut want_free, mut want_occupied) = (Vec::new(), Vec::new());
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let key = Key([x, y, z]);
                        let (f, o) = (rng.random_bool(density), rng.random_bool(density / 4.0));
                        if f {
                            super::super::mark(&free.bits, free.index(&key));
                        }
                        if o {
                            super::super::mark(&occupied.bits, occupied.index(&key));
                            want_occupied.push(key.morton());
                        } else if f {
                            want_free.push(key.morton());
                        }
                    }
                }
            }
            want_free.sort_unstable();
            want_occupied.sort_unstable();
            free.list_marked(&mut occupied);
            assert_eq!(free.codes, want_free, "round {round}");
            assert_eq!(occupied.codes, want_occupied, "round {round}");
        }
    }
}
