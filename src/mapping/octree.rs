//! A sparse probabilistic octree in log-odds, laid out like OctoMap's
//! (docs/math.md §5.2; docs/octomap.md): fixed depth 16, per axis
//! `key = floor(coord / res) + 32768`, the child at depth `d` chosen by bit
//! `15 − d` of the keys (bit 0 from x, 1 from y, 2 from z). An absent node is
//! unknown; an inner node holds the maximum of its children; eight equal leaf
//! children are pruned into their parent.
//!
//! Storage, by level (docs/performance.md, memory):
//! - depths 0–14: 8-byte nodes (`f32` log-odds, `u32` index of a block of
//!   eight children);
//! - depth 15, the parents of finest cells: 4 bytes each (`ParentSlot`).
//!   A parent stores no value: it answers the maximum of its known cells,
//!   which is what an inner node holds. A pruned depth-15 leaf keeps its
//!   log-odds in a pool of leaf values;
//! - depth 16, the finest cells: bare `f32` log-odds, 4 bytes each.
//!
//! An unknown slot holds NaN. Freed blocks and slots are reused.

use crate::geometry::{floor, Point3};

mod key;
mod limits;
mod log_odds;
mod pool;
mod update;
pub use key::Key;
pub use limits::{check_span, span, RESOLUTIONS};
pub use log_odds::{logodds, Clamp, LOG_ODDS_HIT, LOG_ODDS_MISS};
use pool::{max_known, Parent, ParentSlot, Pool};

/// Depth of the finest level.
pub const DEPTH: u8 = 16;
/// Depth of the parents of finest cells.
const PARENT: u8 = DEPTH - 1;
pub(crate) const CENTER: i64 = 1 << 15;
const NO_CHILDREN: u32 = u32::MAX;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    value: f32,
    children: u32,
}

const UNKNOWN: Node = Node {
    value: f32::NAN,
    children: NO_CHILDREN,
};

/// A leaf as reported by [`Octree::leaves`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leaf {
    /// The smallest key inside the leaf.
    pub key: Key,
    /// Its depth (16 = finest voxel).
    pub depth: u8,
    /// Its log-odds.
    pub value: f32,
}

/// Counts and memory of a tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TreeStats {
    /// Known nodes (the root included).
    pub nodes: usize,
    /// Known nodes without children.
    pub leaves: usize,
    /// Nodes with children.
    pub inner: usize,
    /// Bytes held by the node pools (capacity included).
    pub bytes: usize,
}

/// The probabilistic octree.
#[derive(Clone)]
pub struct Octree {
    resolution: f64,
    /// Nodes of depths 0–14; the children of a depth-14 node are in `parents`.
    nodes: Pool<Node>,
    /// Depth-15 nodes; their children are in `finest`.
    parents: Pool<ParentSlot>,
    /// The log-odds of depth-15 leaves.
    leaf_values: Pool<f32>,
    /// The finest cells' log-odds, in blocks of eight.
    finest: Pool<f32>,
}

/// A node of the tree for the file formats: its index in its level's pool,
/// and its depth.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct NodeId {
    index: usize,
    depth: u8,
}

impl NodeId {
    /// Its depth (0: the root, 16: a finest cell).
    pub(crate) fn depth(self) -> u8 {
        self.depth
    }

    /// The `i`-th node of the block starting at `self`.
    pub(crate) fn offset(self, i: usize) -> NodeId {
        NodeId {
            index: self.index + i,
            depth: self.depth,
        }
    }
}

impl std::fmt::Debug for Octree {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Octree {{ resolution: {}, {:?} }}",
            self.resolution,
            self.stats()
        )
    }
}

impl PartialEq for Octree {
    /// Two trees are equal when they hold the same leaves (pool layout aside).
    fn eq(&self, other: &Self) -> bool {
        self.resolution == other.resolution && self.leaves() == other.leaves()
    }
}

impl Octree {
    /// An empty (all unknown) tree with the given finest voxel edge (m).
    pub fn new(resolution: f64) -> Self {
        assert!(
            resolution > 0.0 && resolution.is_finite(),
            "resolution must be positive"
        );
        Self {
            resolution,
            nodes: Pool::with(vec![UNKNOWN]),
            parents: Pool::default(),
            leaf_values: Pool::default(),
            finest: Pool::default(),
        }
    }

    /// The finest voxel edge (m).
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// The edge of a node at `depth` (m).
    pub fn node_size(&self, depth: u8) -> f64 {
        self.resolution * (1u32 << (DEPTH - depth)) as f64
    }

    /// The key of the finest cell containing `p`, if inside the tree's cube:
    /// OctoMap's `coordToKey`, `⌊x · (1/res)⌋ + 2¹⁵` (a product by the
    /// factor, as OctoMap computes it: a division rounds the other way for
    /// some points on a cell border, 0.3 at 5 cm among them).
    #[inline]
    pub fn key(&self, p: &Point3) -> Option<Key> {
        let mut k = [0u16; 3];
        let factor = 1.0 / self.resolution;
        for (axis, out) in k.iter_mut().enumerate() {
            let v = p[axis] * factor;
            // Far outside (or NaN): no key. This runs twice per ray, hence
            // `geometry::floor` (no libm call).
            if v.is_nan() || v.abs() >= 1e9 {
                return None;
            }
            let v = floor(v) + CENTER;
            if !(0..(1 << 16)).contains(&v) {
                return None;
            }
            *out = v as u16;
        }
        Some(Key(k))
    }

    /// The centre of the node at `depth` containing `key`.
    pub fn center(&self, key: &Key, depth: u8) -> Point3 {
        let shift = DEPTH - depth;
        let half = if shift == 0 {
            0.5
        } else {
            (1u32 << (shift - 1)) as f64
        };
        let c = |k: u16| {
            ((((k as i64) >> shift) << shift) - CENTER) as f64 * self.resolution
                + half * self.resolution
        };
        Point3::new(c(key.0[0]), c(key.0[1]), c(key.0[2]))
    }

    /// The lattice point `key + offset` (cell corners): offset 0 is the
    /// finest cell's lower corner, 1 its upper one along that axis. Computed
    /// from integers, so the cells sharing a corner agree on it to the bit.
    #[inline]
    pub fn lattice_point(&self, key: &Key, offset: [u16; 3]) -> Point3 {
        let c = |axis: usize| {
            (key.0[axis] as i64 + offset[axis] as i64 - CENTER) as f64 * self.resolution
        };
        Point3::new(c(0), c(1), c(2))
    }

    /// The first of the children of the node at `depth` < 16 (an index
    /// into the next level's pool), if it has them.
    #[inline]
    fn first_child(&self, node: usize, depth: u8) -> Option<usize> {
        if depth == PARENT {
            match self.parents.items[node].get() {
                Parent::Cells(first) => Some(first),
                _ => None,
            }
        } else {
            let block = self.nodes.items[node].children;
            (block != NO_CHILDREN).then_some(block as usize)
        }
    }

    /// The log-odds of the node at `depth` (NaN: unknown); an inner node
    /// answers the maximum of its known children.
    #[inline]
    fn value_at_depth(&self, node: usize, depth: u8) -> f32 {
        if depth == DEPTH {
            self.finest.items[node]
        } else if depth == PARENT {
            self.parent_value(self.parents.items[node])
        } else {
            self.nodes.items[node].value
        }
    }

    #[inline]
    fn parent_value(&self, slot: ParentSlot) -> f32 {
        self.parent_entry(slot).0
    }

    /// A depth-15 node's log-odds (NaN: unknown; with cells, their maximum)
    /// and whether it is a leaf.
    #[inline]
    fn parent_entry(&self, slot: ParentSlot) -> (f32, bool) {
        match slot.get() {
            Parent::Unknown => (f32::NAN, true),
            Parent::Leaf(index) => (self.leaf_values.items[index], true),
            Parent::Cells(first) => (max_known(&self.finest.items[first..first + 8]), false),
        }
    }

    /// Sets the value of a node without children (NaN: unknown) at `depth`
    /// < 16. A depth-15 node with children stores no value: left as it is.
    fn set_leaf_value(&mut self, node: usize, depth: u8, value: f32) {
        if depth != PARENT {
            self.nodes.items[node].value = value;
            return;
        }
        match (self.parents.items[node].get(), value.is_nan()) {
            (Parent::Cells(_), _) | (Parent::Unknown, true) => {}
            (Parent::Unknown, false) => {
                self.parents.items[node] = ParentSlot::leaf(self.leaf_values.take_one(value));
            }
            (Parent::Leaf(index), false) => self.leaf_values.items[index] = value,
            (Parent::Leaf(index), true) => {
                self.leaf_values.free_one(index);
                self.parents.items[node] = ParentSlot::UNKNOWN;
            }
        }
    }

    /// Gives the childless `node` (at `depth` < 16) eight children, all
    /// `value`; returns the first.
    fn give_children(&mut self, node: usize, depth: u8, value: f32) -> usize {
        if depth == PARENT {
            if let Parent::Leaf(index) = self.parents.items[node].get() {
                self.leaf_values.free_one(index);
            }
            let first = self.finest.take_block(value);
            self.parents.items[node] = ParentSlot::cells(first);
            return first;
        }
        let first = if depth + 1 == PARENT {
            let first = self.parents.take_block(ParentSlot::UNKNOWN);
            if !value.is_nan() {
                for child in first..first + 8 {
                    self.parents.items[child] = ParentSlot::leaf(self.leaf_values.take_one(value));
                }
            }
            first
        } else {
            self.nodes.take_block(Node {
                value,
                children: NO_CHILDREN,
            })
        };
        self.nodes.items[node].children =
            u32::try_from(first).expect("fewer than 2^32 nodes above depth 15");
        first
    }

    /// Max of the known children into `node` (at `depth` < 16); prunes
    /// eight equal leaves.
    fn refresh(&mut self, node: usize, depth: u8) {
        if depth == PARENT {
            // The value is the cells' max, read when asked: only prune.
            let Parent::Cells(first) = self.parents.items[node].get() else {
                return;
            };
            let cells = &self.finest.items[first..first + 8];
            let value = cells[0];
            if !value.is_nan() && cells.iter().all(|&v| v == value) {
                self.finest.free_block(first);
                self.parents.items[node] = ParentSlot::leaf(self.leaf_values.take_one(value));
            }
            return;
        }
        let block = self.nodes.items[node].children;
        if block == NO_CHILDREN {
            return;
        }
        let first = block as usize;
        // The children's values; and whether all of them are leaves.
        let (values, leaves): ([f32; 8], bool) = if depth + 1 == PARENT {
            let mut leaves = true;
            let slots = &self.parents.items[first..first + 8];
            let values = std::array::from_fn(|i| {
                let (value, leaf) = self.parent_entry(slots[i]);
                leaves &= leaf;
                value
            });
            (values, leaves)
        } else {
            let children = &self.nodes.items[first..first + 8];
            (
                std::array::from_fn(|i| children[i].value),
                children.iter().all(|c| c.children == NO_CHILDREN),
            )
        };
        let max = max_known(&values);
        let prunable = leaves && !values[0].is_nan() && values.iter().all(|&v| v == values[0]);
        self.nodes.items[node].value = max;
        if !prunable {
            return;
        }
        self.nodes.items[node].children = NO_CHILDREN;
        if depth + 1 == PARENT {
            for child in first..first + 8 {
                if let Parent::Leaf(index) = self.parents.items[child].get() {
                    self.leaf_values.free_one(index);
                }
            }
            self.parents.free_block(first);
        } else {
            self.nodes.free_block(first);
        }
    }

    /// The log-odds of the node at `depth` (or the coarser leaf) containing
    /// `key`; `None` when unknown. An inner node answers the max of its children.
    pub fn query(&self, key: &Key, depth: u8) -> Option<f32> {
        let (mut node, mut d) = (0usize, 0u8);
        while d < depth {
            let Some(first) = self.first_child(node, d) else {
                break;
            };
            node = first + key.child_at(d);
            d += 1;
        }
        let v = self.value_at_depth(node, d);
        (!v.is_nan()).then_some(v)
    }

    /// The log-odds at a point, at the finest level.
    pub fn value_at(&self, p: &Point3) -> Option<f32> {
        self.key(p).and_then(|k| self.query(&k, DEPTH))
    }

    /// Every known leaf, depth first in child order (deterministic).
    pub fn leaves(&self) -> Vec<Leaf> {
        let mut out = Vec::new();
        self.visit_leaves(|leaf| out.push(leaf));
        out
    }

    /// Calls `f` on every known leaf, depth first in child order.
    pub fn visit_leaves(&self, mut f: impl FnMut(Leaf)) {
        let mut stack = vec![(0usize, 0u8, [0u16; 3])];
        while let Some((node, depth, key)) = stack.pop() {
            let id = NodeId { index: node, depth };
            let Some(block) = self.children(id) else {
                let value = self.value(id);
                if !value.is_nan() {
                    f(Leaf {
                        key: Key(key),
                        depth,
                        value,
                    });
                }
                continue;
            };
            let bit = 15 - depth as u32;
            for i in (0..8usize).rev() {
                let mut k = key;
                for (axis, kk) in k.iter_mut().enumerate() {
                    *kk |= (((i >> axis) & 1) as u16) << bit;
                }
                stack.push((block.index + i, depth + 1, k));
            }
        }
    }

    /// Bytes the node pools hold (their capacity): what the tree costs in
    /// memory while it grows.
    pub fn pool_bytes(&self) -> usize {
        self.nodes.slot_bytes()
            + self.parents.slot_bytes()
            + self.leaf_values.slot_bytes()
            + self.finest.slot_bytes()
    }

    /// Releases the pools' spare capacity (after the last update).
    pub fn shrink_to_fit(&mut self) {
        self.nodes.shrink_to_fit();
        self.parents.shrink_to_fit();
        self.leaf_values.shrink_to_fit();
        self.finest.shrink_to_fit();
    }

    /// Node counts and pool memory.
    pub fn stats(&self) -> TreeStats {
        let (mut nodes, mut leaves, mut inner) = (0, 0, 0);
        let mut stack = vec![NodeId { index: 0, depth: 0 }];
        while let Some(id) = stack.pop() {
            let children = self.children(id);
            // (A node with children is known: its value is not needed.)
            if children.is_none() && self.value(id).is_nan() {
                continue;
            }
            nodes += 1;
            match children {
                None => leaves += 1,
                Some(block) => {
                    inner += 1;
                    stack.extend((0..8).map(|i| block.offset(i)));
                }
            }
        }
        TreeStats {
            nodes,
            leaves,
            inner,
            bytes: self.nodes.bytes()
                + self.parents.bytes()
                + self.leaf_values.bytes()
                + self.finest.bytes(),
        }
    }

    /// Replaces every leaf value by `f(value)` (for example, maximum
    /// likelihood), then prunes what became equal.
    pub fn map_values(&mut self, f: impl Fn(f32) -> f32) {
        self.map_node(0, 0, &f);
    }

    fn map_node(&mut self, node: usize, depth: u8, f: &impl Fn(f32) -> f32) {
        if depth == DEPTH {
            let v = self.finest.items[node];
            if !v.is_nan() {
                self.finest.items[node] = f(v);
            }
            return;
        }
        let Some(first) = self.first_child(node, depth) else {
            let v = self.value_at_depth(node, depth);
            if !v.is_nan() {
                self.set_leaf_value(node, depth, f(v));
            }
            return;
        };
        for child in first..first + 8 {
            self.map_node(child, depth + 1, f);
        }
        self.refresh(node, depth);
    }

    /// A node's value (NaN: unknown).
    #[inline]
    fn value(&self, id: NodeId) -> f32 {
        self.value_at_depth(id.index, id.depth)
    }

    /// The first of a node's eight children, if it has them.
    #[inline]
    fn children(&self, id: NodeId) -> Option<NodeId> {
        if id.depth == DEPTH {
            return None;
        }
        self.first_child(id.index, id.depth).map(|index| NodeId {
            index,
            depth: id.depth + 1,
        })
    }

    // --- raw access for the file formats ---------------------------------

    /// The root.
    pub(crate) fn root(&self) -> NodeId {
        NodeId { index: 0, depth: 0 }
    }

    /// A node's value (NaN: unknown) and the first of its children.
    pub(crate) fn raw(&self, node: NodeId) -> (f32, Option<NodeId>) {
        (self.value(node), self.children(node))
    }

    /// Sets a node's value (file reading). A depth-15 node with children
    /// keeps answering the maximum of its cells (an inner node's value).
    pub(crate) fn set_raw_value(&mut self, node: NodeId, value: f32) {
        if node.depth == DEPTH {
            self.finest.items[node.index] = value;
        } else {
            self.set_leaf_value(node.index, node.depth, value);
        }
    }

    /// Gives a node above the finest level eight unknown children (file
    /// reading); returns the first.
    pub(crate) fn raw_expand(&mut self, node: NodeId) -> NodeId {
        assert!(node.depth < DEPTH, "a finest cell has no children");
        assert!(
            self.first_child(node.index, node.depth).is_none(),
            "a node is given children once"
        );
        NodeId {
            index: self.give_children(node.index, node.depth, f32::NAN),
            depth: node.depth + 1,
        }
    }
}

#[cfg(test)]
mod tests;
