//! The octree's updates: one finest cell, a region, or a scan's changes in
//! depth-first order walking the tree once (docs/math.md §5.2).

use super::{Clamp, Key, Octree, DEPTH};

impl Octree {
    /// Walks from the root to the node at `depth` containing `key`, giving
    /// children to the nodes on the way (copies of a pruned leaf, or unknown)
    /// and recording the path. Stops with `None` at a pruned leaf whose value
    /// `unchanged` says the update would not change. The index returned is
    /// in the finest pool when `depth` is 16.
    fn descend(
        &mut self,
        key: &Key,
        depth: u8,
        path: &mut [usize; DEPTH as usize],
        unchanged: impl Fn(f32) -> bool,
    ) -> Option<usize> {
        let mut node = 0usize;
        for d in 0..depth {
            path[d as usize] = node;
            let first = match self.first_child(node, d) {
                Some(first) => first,
                None => {
                    let current = self.value_at_depth(node, d);
                    if !current.is_nan() && unchanged(current) {
                        return None;
                    }
                    self.give_children(node, d, current)
                }
            };
            node = first + key.child_at(d);
        }
        Some(node)
    }

    /// Adds `delta` to the finest cell `key` (unknown counts as 0), clamps.
    pub fn update(&mut self, key: &Key, delta: f32, clamp: Clamp) {
        let mut path = [0usize; DEPTH as usize];
        // A pruned leaf already at the target value (clamped): nothing changes.
        let Some(node) = self.descend(key, DEPTH, &mut path, |v| clamp.apply(v + delta) == v)
        else {
            return;
        };
        let leaf = &mut self.finest.items[node];
        let base = if leaf.is_nan() { 0.0 } else { *leaf };
        *leaf = clamp.apply(base + delta);
        for depth in (0..DEPTH).rev() {
            self.refresh(path[depth as usize], depth);
        }
    }

    /// Adds `delta` to each finest cell of `codes` (Morton codes, sorted
    /// ascending, no repeats) — the same result as [`Octree::update`] on each,
    /// but walking the tree once ([`Octree::update_depth_first`]).
    pub fn update_sorted(&mut self, codes: &[u64], delta: f32, clamp: Clamp) {
        self.update_depth_first(codes.iter().map(|&code| (code, DEPTH, delta)), clamp);
    }

    /// Applies `(code, depth, delta)` changes in depth-first order (Morton
    /// code of the node's first cell ascending, no change inside another):
    /// at depth 16 as [`Octree::update`], above it as
    /// [`Octree::update_region`] — the same tree as those calls one by one
    /// (tested), but walking the tree once: consecutive changes share their
    /// path from the root, and each inner node is refreshed once, when the
    /// walk leaves it.
    pub fn update_depth_first(
        &mut self,
        changes: impl IntoIterator<Item = (u64, u8, f32)>,
        clamp: Clamp,
    ) {
        let mut path = [0usize; DEPTH as usize + 1];
        let mut valid = 0usize; // path[0..=valid] is the current path
        let mut previous: Option<u64> = None;
        for (code, target, delta) in changes {
            let target = usize::from(target);
            let common = match previous {
                // Depth of the deepest node shared with the previous change.
                Some(p) => (((p ^ code).leading_zeros() as usize).saturating_sub(16) / 3)
                    .min(valid)
                    .min(target),
                None => 0,
            };
            // Leave the previous change's nodes below `common` (a region's
            // own node was refreshed by `add_subtree`).
            for d in (common + 1..valid.min(DEPTH as usize)).rev() {
                self.refresh(path[d], d as u8);
            }
            let mut node = path[common];
            let mut depth = common;
            let mut skipped = false;
            while depth < target {
                let first = match self.first_child(node, depth as u8) {
                    Some(first) => first,
                    None => {
                        // A pruned leaf that a finest-cell change leaves as
                        // it is (clamped) stays pruned, as in `update`.
                        let current = self.value_at_depth(node, depth as u8);
                        if target == DEPTH as usize
                            && !current.is_nan()
                            && clamp.apply(current + delta) == current
                        {
                            skipped = true;
                            break;
                        }
                        self.give_children(node, depth as u8, current)
                    }
                };
                node = first + ((code >> (3 * (DEPTH as usize - 1 - depth))) & 7) as usize;
                depth += 1;
                path[depth] = node;
            }
            if !skipped {
                if target == DEPTH as usize {
                    let leaf = &mut self.finest.items[node];
                    let base = if leaf.is_nan() { 0.0 } else { *leaf };
                    *leaf = clamp.apply(base + delta);
                } else {
                    self.add_subtree(node, target as u8, delta, clamp);
                }
            }
            valid = depth;
            previous = Some(code);
        }
        for d in (0..valid.min(DEPTH as usize)).rev() {
            self.refresh(path[d], d as u8);
        }
    }

    /// Adds `delta` to every cell of the node at `depth` containing `key`,
    /// unknown cells included (they start at 0); keeps the tree coarse where
    /// it already is.
    pub fn update_region(&mut self, key: &Key, depth: u8, delta: f32, clamp: Clamp) {
        let mut path = [0usize; DEPTH as usize];
        let Some(node) = self.descend(key, depth, &mut path, |_| false) else {
            return;
        };
        self.add_subtree(node, depth, delta, clamp);
        for d in (0..depth).rev() {
            self.refresh(path[d as usize], d);
        }
    }

    fn add_subtree(&mut self, node: usize, depth: u8, delta: f32, clamp: Clamp) {
        let add = |v: f32| clamp.apply(if v.is_nan() { delta } else { v + delta });
        if depth == DEPTH {
            self.finest.items[node] = add(self.finest.items[node]);
            return;
        }
        let Some(first) = self.first_child(node, depth) else {
            let value = add(self.value_at_depth(node, depth));
            self.set_leaf_value(node, depth, value);
            return;
        };
        for child in first..first + 8 {
            self.add_subtree(child, depth + 1, delta, clamp);
        }
        self.refresh(node, depth);
    }
}
