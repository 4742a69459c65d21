//! The index's cells, stored as dense blocks of 8 × 8 × 8 finest cells
//! found through a hash of the block's key.
//!
//! \[DESIGN\] A scan's surface bands fill a thin shell of cells, and
//! neighbouring beams (consecutive in the index's walk) reach the same
//! cells. A hash of single cells spent most of the index's time in cache
//! misses of its table; a block holds a band's cells and its neighbours', so
//! the walk finds its block through the last one it used (a compare) and the
//! cell by an offset. A block holds 512 cells of 16 bytes (8 KiB); a scan at
//! 2 cm fills a few hundred.

use super::Held;
use crate::mapping::octree::Key;
use rustc_hash::FxHashMap;

/// Cells along each edge of a block, as a shift.
pub(super) const SIDE_BITS: u32 = 3;
/// Cells of a block.
pub(super) const CELLS: usize = 1 << (3 * SIDE_BITS);
/// The low bits of a coordinate: the cell's place in its block.
const LOW: u16 = (1 << SIDE_BITS) - 1;

/// A value no block packs to (a block key uses 39 bits).
const NO_BLOCK: u64 = u64::MAX;

/// A cell no beam has raised: value 0, never settled.
pub(super) const EMPTY: Held = Held {
    value: 0.0,
    settled_beyond: f64::INFINITY,
};

/// Finest cells' [`Held`] values in blocks (absent: [`EMPTY`]).
#[derive(Clone, Debug, Default)]
pub(super) struct Blocks {
    index: FxHashMap<u64, u32>,
    blocks: Vec<Box<[Held; CELLS]>>,
}

/// The block a walk used last: its packed key and its place.
#[derive(Clone, Copy, Debug)]
pub(super) struct Cursor(u64, u32);

impl Default for Cursor {
    fn default() -> Self {
        Self(NO_BLOCK, 0)
    }
}

/// The packed key of the block of `key` and the cell's place in it.
#[inline]
pub(super) fn split(key: &Key) -> (u64, usize) {
    let [x, y, z] = key.0.map(u64::from);
    let block = (x >> SIDE_BITS) | (y >> SIDE_BITS) << 13 | (z >> SIDE_BITS) << 26;
    let [lx, ly, lz] = key.0.map(|c| usize::from(c & LOW));
    (block, lx | ly << SIDE_BITS | lz << (2 * SIDE_BITS))
}

impl Blocks {
    /// The cell `key`'s value, its block created empty if it has none;
    /// `cursor` is the block this walk used last (most cells of a walk fall
    /// in it).
    #[inline]
    pub(super) fn cell_mut(&mut self, key: &Key, cursor: &mut Cursor) -> &mut Held {
        let (block, place) = split(key);
        if cursor.0 != block {
            let next = self.blocks.len() as u32;
            let at = *self.index.entry(block).or_insert(next);
            if at == next {
                self.blocks.push(Box::new([EMPTY; CELLS]));
            }
            *cursor = Cursor(block, at);
        }
        &mut self.blocks[cursor.1 as usize][place]
    }

    /// The cells of the block holding `key` (an 8 × 8 × 8 block aligned on
    /// multiples of 8), if some beam raised one of them.
    #[inline]
    pub(super) fn block(&self, key: &Key) -> Option<&[Held; CELLS]> {
        let (block, _) = split(key);
        self.index.get(&block).map(|&at| &*self.blocks[at as usize])
    }

    /// Every cell some beam raised, with its block's key and place, in no
    /// particular order.
    pub(super) fn raised(&self) -> impl Iterator<Item = ((u64, usize), Held)> + '_ {
        self.index.iter().flat_map(move |(&block, &at)| {
            self.blocks[at as usize]
                .iter()
                .enumerate()
                .filter(|(_, held)| held.value > 0.0)
                .map(move |(place, held)| ((block, place), *held))
        })
    }

    /// The cell-wise maximum of two indexes (each cell's larger value;
    /// equal values are equal [`Held`]s), whatever their order.
    pub(super) fn merge(self, other: Self) -> Self {
        let (mut into, from) = if self.blocks.len() < other.blocks.len() {
            (other, self)
        } else {
            (self, other)
        };
        let mut from_blocks: Vec<Option<Box<[Held; CELLS]>>> =
            from.blocks.into_iter().map(Some).collect();
        for (block, at) in from.index {
            let cells = from_blocks[at as usize].take().expect("one key per block");
            match into.index.get(&block) {
                Some(&mine) => {
                    for (slot, held) in into.blocks[mine as usize].iter_mut().zip(cells.iter()) {
                        if held.value > slot.value {
                            *slot = *held;
                        }
                    }
                }
                None => {
                    into.index.insert(block, into.blocks.len() as u32);
                    into.blocks.push(cells);
                }
            }
        }
        into
    }
}
