//! The octree's storage: pools of slots that reuse what they free, and the
//! four-byte slot of a depth-15 node (a parent of finest cells).

/// A growable array of slots, handed out in blocks of eight (children) or
/// one by one (the values of depth-15 leaves), and reused once freed. A
/// pool is used in one of the two ways only.
#[derive(Clone, Debug)]
pub(super) struct Pool<T> {
    pub items: Vec<T>,
    /// Freed blocks (their first index) or freed single slots.
    free: Vec<u32>,
}

impl<T> Default for Pool<T> {
    fn default() -> Self {
        Self {
            items: Vec::new(),
            free: Vec::new(),
        }
    }
}

impl<T: Copy> Pool<T> {
    /// A pool holding `items`.
    pub fn with(items: Vec<T>) -> Self {
        Self {
            items,
            free: Vec::new(),
        }
    }

    /// Eight slots set to `fill`: a freed block if any, else new ones at the
    /// end; the first one's index.
    pub fn take_block(&mut self, fill: T) -> usize {
        if let Some(first) = self.free.pop() {
            let first = first as usize;
            self.items[first..first + 8].fill(fill);
            first
        } else {
            let first = self.items.len();
            self.items.extend_from_slice(&[fill; 8]);
            first
        }
    }

    /// Gives back the block of eight starting at `first`.
    pub fn free_block(&mut self, first: usize) {
        self.free
            .push(u32::try_from(first).expect("a pool holds fewer than 2^32 slots"));
    }

    /// One slot set to `value`; its index.
    pub fn take_one(&mut self, value: T) -> usize {
        if let Some(index) = self.free.pop() {
            self.items[index as usize] = value;
            index as usize
        } else {
            self.items.push(value);
            self.items.len() - 1
        }
    }

    /// Gives back the single slot `index`.
    pub fn free_one(&mut self, index: usize) {
        self.free
            .push(u32::try_from(index).expect("a pool holds fewer than 2^32 slots"));
    }

    /// Bytes held, spare capacity included.
    pub fn bytes(&self) -> usize {
        self.items.capacity() * std::mem::size_of::<T>() + self.free.capacity() * 4
    }

    /// Bytes held by the slots alone (what grows with the map).
    pub fn slot_bytes(&self) -> usize {
        self.items.capacity() * std::mem::size_of::<T>()
    }

    /// Releases the spare capacity.
    pub fn shrink_to_fit(&mut self) {
        self.items.shrink_to_fit();
        self.free.shrink_to_fit();
    }
}

/// What a depth-15 node is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Parent {
    /// Unknown, without children.
    Unknown,
    /// A leaf (eight equal cells pruned): the index of its log-odds in the
    /// pool of leaf values.
    Leaf(usize),
    /// The parent of eight finest cells: the first one's index. Its value is
    /// not stored: it is the maximum of its known cells.
    Cells(usize),
}

/// A depth-15 node in four bytes: `u32::MAX` when unknown, a leaf's value
/// index with the top bit set, or the block number of its finest cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct ParentSlot(u32);

const LEAF: u32 = 1 << 31;

impl ParentSlot {
    /// An unknown node.
    pub const UNKNOWN: Self = Self(u32::MAX);

    /// A leaf whose log-odds is at `value_index` in the leaf values.
    pub fn leaf(value_index: usize) -> Self {
        let index = u32::try_from(value_index)
            .ok()
            .filter(|&i| i < LEAF - 1)
            .expect("fewer than 2^31 depth-15 leaves");
        Self(index | LEAF)
    }

    /// The parent of the finest cells `first..first + 8`.
    pub fn cells(first: usize) -> Self {
        let block = u32::try_from(first / 8)
            .ok()
            .filter(|&b| b < LEAF)
            .expect("fewer than 2^31 blocks of finest cells");
        Self(block)
    }

    /// What the slot holds.
    #[inline]
    pub fn get(self) -> Parent {
        if self.0 == u32::MAX {
            Parent::Unknown
        } else if self.0 & LEAF != 0 {
            Parent::Leaf((self.0 & !LEAF) as usize)
        } else {
            Parent::Cells(self.0 as usize * 8)
        }
    }
}

/// The maximum of the known values (NaN when none is): `f32::max` returns
/// the other argument when one is NaN.
#[inline]
pub(super) fn max_known(values: &[f32]) -> f32 {
    values.iter().fold(f32::NAN, |max, &v| max.max(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_parent_slot_says_what_it_was_given() {
        assert_eq!(ParentSlot::UNKNOWN.get(), Parent::Unknown);
        for index in [0, 1, 7_654_321, (LEAF - 2) as usize] {
            assert_eq!(ParentSlot::leaf(index).get(), Parent::Leaf(index));
        }
        for first in [0, 8, 8 * 123_457, 8 * (LEAF as usize - 1)] {
            assert_eq!(ParentSlot::cells(first).get(), Parent::Cells(first));
        }
    }

    #[test]
    fn the_maximum_skips_unknown_values() {
        let nan = f32::NAN;
        assert!(max_known(&[nan; 8]).is_nan());
        assert_eq!(max_known(&[nan, -2.0, nan, -0.5, nan, nan, nan, nan]), -0.5);
        assert_eq!(max_known(&[3.5, nan, nan, nan, nan, nan, nan, -1.0]), 3.5);
    }

    #[test]
    fn pools_reuse_what_they_free() {
        let mut blocks = Pool::with(vec![0u8]);
        let a = blocks.take_block(1);
        let b = blocks.take_block(2);
        assert_eq!((a, b), (1, 9));
        blocks.free_block(a);
        assert_eq!(blocks.take_block(3), a);
        assert_eq!(blocks.items[a..a + 8], [3; 8]);
        assert_eq!(blocks.items.len(), 17);
        let mut ones = Pool::with(Vec::new());
        let (x, y) = (ones.take_one(1.5f32), ones.take_one(2.5));
        ones.free_one(x);
        assert_eq!(ones.take_one(4.0), x);
        assert_eq!(ones.items, [4.0, 2.5]);
        assert_eq!(y, 1);
    }
}
