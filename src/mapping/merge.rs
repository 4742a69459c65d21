//! Merging a local spherical grid into the global octree by intersection
//! search (MATH.md §5.3): descend only into octree cells that meet the grid's
//! support, stop where the grid is uniformly unknown, update a whole cell at
//! once where the grid is homogeneous over it, and fuse in log-odds.

use super::octree::{Clamp, Key, Octree, DEPTH};
use super::spherical::LocalGrid;

/// The merge's tolerances (log-odds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MergeOptions {
    /// A cell whose bins span less than this is updated whole with their mean
    /// (default 0.2).
    pub homogeneous: f32,
    /// Bins within ±this of 0 carry no information (default 0.05).
    pub unknown: f32,
    /// The map-level clamp.
    pub clamp: Clamp,
}

impl Default for MergeOptions {
    fn default() -> Self {
        Self {
            homogeneous: 0.2,
            unknown: 0.05,
            clamp: Clamp::OCTOMAP,
        }
    }
}

/// Counters of one merge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MergeStats {
    /// Octree cells examined.
    pub visited: usize,
    /// Cells updated whole above the finest level.
    pub coarse_updates: usize,
    /// Finest cells updated one by one.
    pub fine_updates: usize,
}

/// Fuses `grid` into `tree`.
pub fn merge(tree: &mut Octree, grid: &LocalGrid, options: &MergeOptions) -> MergeStats {
    let mut stats = MergeStats::default();
    recurse(tree, grid, options, Key([0, 0, 0]), 0, &mut stats);
    stats
}

fn recurse(
    tree: &mut Octree,
    grid: &LocalGrid,
    options: &MergeOptions,
    key: Key,
    depth: u8,
    stats: &mut MergeStats,
) {
    stats.visited += 1;
    let centre = tree.center(&key, depth).coords;
    // The cube's circumscribed ball: a conservative superset of its bins.
    let radius = tree.node_size(depth) * 0.5 * 3f64.sqrt();
    let Some((bins, outside)) = grid.ball_bins(&centre, radius) else {
        return;
    };
    let summary = grid.query(bins[0], bins[1], bins[2]);
    let (mut min, mut max) = (summary.min, summary.max);
    if outside {
        // Whatever lies outside the grid is unknown (0).
        min = min.min(0.0);
        max = max.max(0.0);
    }
    if summary.known == 0 || max.abs().max(min.abs()) < options.unknown {
        return;
    }
    if max - min < options.homogeneous {
        tree.update_region(&key, depth, summary.mean, options.clamp);
        if depth == DEPTH {
            stats.fine_updates += 1;
        } else {
            stats.coarse_updates += 1;
        }
        return;
    }
    if depth == DEPTH {
        let v = grid.value_at(&centre);
        if v.abs() >= options.unknown {
            tree.update(&key, v, options.clamp);
            stats.fine_updates += 1;
        }
        return;
    }
    let bit = 15 - depth as u32;
    for child in 0..8u16 {
        let mut k = key;
        for (axis, kk) in k.0.iter_mut().enumerate() {
            *kk |= ((child >> axis) & 1) << bit;
        }
        recurse(tree, grid, options, k, depth + 1, stats);
    }
}
