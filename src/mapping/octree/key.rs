//! An octree cell's integer coordinates at the finest level, and their Morton
//! order (the tree's depth-first order).

/// Integer cell coordinates at the finest level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Key(pub [u16; 3]);

impl Key {
    /// The child index (0–7) taken at depth `depth` (0 = root).
    #[inline]
    pub fn child_at(&self, depth: u8) -> usize {
        let bit = 15 - depth as u32;
        (((self.0[0] >> bit) & 1)
            | (((self.0[1] >> bit) & 1) << 1)
            | (((self.0[2] >> bit) & 1) << 2)) as usize
    }

    /// The key of child `index` (0–7, as [`Key::child_at`] numbers them) of
    /// the node at `depth` holding this key, whose lower bits are clear.
    #[inline]
    pub fn child(&self, depth: u8, index: u16) -> Key {
        let bit = 15 - depth as u32;
        Key(std::array::from_fn(|axis| {
            self.0[axis] | ((index >> axis) & 1) << bit
        }))
    }

    /// The Morton code: bits of x, y, z interleaved so that the top three bits
    /// are the root's child index; sorting by it is the tree's depth-first order.
    #[inline]
    pub fn morton(&self) -> u64 {
        spread(self.0[0]) | spread(self.0[1]) << 1 | spread(self.0[2]) << 2
    }

    /// The inverse of [`Key::morton`].
    #[inline]
    pub fn from_morton(m: u64) -> Self {
        Key([compact(m), compact(m >> 1), compact(m >> 2)])
    }

    /// A 48-bit packing, for hashing and sorting.
    #[inline]
    pub fn packed(&self) -> u64 {
        self.0[0] as u64 | (self.0[1] as u64) << 16 | (self.0[2] as u64) << 32
    }

    /// The inverse of [`Key::packed`].
    #[inline]
    pub fn unpack(v: u64) -> Self {
        Key([v as u16, (v >> 16) as u16, (v >> 32) as u16])
    }
}

/// Spreads 16 bits to every third bit.
#[inline]
fn spread(v: u16) -> u64 {
    let mut x = v as u64;
    x = (x | x << 16) & 0x0000_ff00_00ff;
    x = (x | x << 8) & 0x00f0_0f00_f00f;
    x = (x | x << 4) & 0x0c30_c30c_30c3;
    (x | x << 2) & 0x2492_4924_9249
}

/// The inverse of [`spread`].
#[inline]
fn compact(m: u64) -> u16 {
    let mut x = m & 0x2492_4924_9249;
    x = (x | x >> 2) & 0x0c30_c30c_30c3;
    x = (x | x >> 4) & 0x00f0_0f00_f00f;
    x = (x | x >> 8) & 0x0000_ff00_00ff;
    ((x | x >> 16) & 0xffff) as u16
}

#[cfg(test)]
mod tests {
    use super::Key;

    #[test]
    fn a_child_is_numbered_as_child_at_reads_it_and_keeps_its_parents_bits() {
        // A node at each depth, its lower bits clear: each child's index reads
        // back, its Morton code is the parent's with the index in the child's
        // three bits, and the parent's own bits stay.
        for depth in 0..16u8 {
            let shift = 16 - depth as u32;
            let parent = Key([0xb6d3, 0x5a97, 0xe1c5].map(|c: u32| {
                if shift == 16 {
                    0
                } else {
                    ((c >> shift) << shift) as u16
                }
            }));
            for index in 0..8u16 {
                let child = parent.child(depth, index);
                assert_eq!(child.child_at(depth), usize::from(index));
                let level_bits = 3 * (15 - u32::from(depth));
                assert_eq!(
                    child.morton(),
                    parent.morton() | u64::from(index) << level_bits
                );
            }
        }
    }
}
