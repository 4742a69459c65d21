//! Merging a viewpoint's local grid into the global octree by intersection
//! search (docs/math.md §5.3) with the cell-occupancy model (§5.4): descend
//! only into octree cells that meet the grid's beams; update a whole cell at
//! once where every beam certifies all of it free; at the finest level combine
//! the chance that a surface lies inside the cell with the share of the cell
//! seen in front of the surface, and fuse in log-odds.

use super::chord::{origin_step, ray_box, Beam, CellModel};
use super::octree::{Clamp, Key, Octree, DEPTH};
use super::opdf::logit;
use super::spherical::{BinBox, LocalGrid};
use crate::geometry::Vector3;

/// Log-odds smaller than this are not written: the cell stays as it was
/// (absent means unknown), as occluded space does in OctoMap.
const NEUTRAL: f32 = 1e-3;

/// How a grid is merged.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MergeOptions {
    /// What one beam says about one cell.
    pub model: CellModel,
    /// The map-level clamp.
    pub clamp: Clamp,
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
    if grid.beam_count() > 0 {
        let mut merger = Merger {
            tree,
            grid,
            options,
            stats: &mut stats,
        };
        merger.recurse(Key([0, 0, 0]), 0);
    }
    stats
}

struct Merger<'a> {
    tree: &'a mut Octree,
    grid: &'a LocalGrid,
    options: &'a MergeOptions,
    stats: &'a mut MergeStats,
}

impl Merger<'_> {
    fn recurse(&mut self, key: Key, depth: u8) {
        self.stats.visited += 1;
        let centre = self.tree.center(&key, depth).coords;
        let half = self.tree.node_size(depth) * 0.5;
        // The cube's circumscribed ball: a conservative superset of its bins.
        let Some(bins) = self.grid.ball_bins(&centre, half * 3f64.sqrt()) else {
            return;
        };
        let s = self.grid.query(bins.azimuth, bins.elevation);
        if s.filled == 0 || bins.range.0 > s.far {
            // No beam reaches the cell: nothing is known about it.
            return;
        }
        if !bins.outside && s.filled == s.bins && bins.range.1 < s.near && bins.range.0 > s.origin {
            // Every beam crosses the whole cell well before its surface band
            // (and its bin's nearest surface) and past the origin step: H = 0
            // and F = 1 in every finest cell, so the model gives p_lo.
            let free = self.options.model.free_log_odds();
            self.tree
                .update_region(&key, depth, free, self.options.clamp);
            if depth == DEPTH {
                self.stats.fine_updates += 1;
            } else {
                self.stats.coarse_updates += 1;
            }
            return;
        }
        if depth == DEPTH {
            if let Some(p) = cell_occupancy(self.grid, &self.options.model, &centre, half, &bins) {
                let l = logit(p) as f32;
                if l.abs() >= NEUTRAL {
                    self.tree.update(&key, l, self.options.clamp);
                    self.stats.fine_updates += 1;
                }
            }
            return;
        }
        let bit = 15 - depth as u32;
        for child in 0..8u16 {
            let mut k = key;
            for (axis, kk) in k.0.iter_mut().enumerate() {
                *kk |= ((child >> axis) & 1) << bit;
            }
            self.recurse(k, depth + 1);
        }
    }
}

/// Whether the centre line of a beam that cannot hold the surface in C
/// crosses C.
fn any_crosses(
    grid: &LocalGrid,
    centre: &Vector3,
    half: f64,
    bins: &BinBox,
    may_hold: &impl Fn(&Beam) -> bool,
) -> bool {
    for a in bins.azimuth.0..=bins.azimuth.1 {
        for e in bins.elevation.0..=bins.elevation.1 {
            let (beams, inverse) = grid.bin_beams(a, e);
            for (beam, inv) in beams.iter().zip(inverse) {
                if !may_hold(beam) && ray_box(&grid.origin, inv, centre, half).is_some() {
                    return true;
                }
            }
        }
    }
    false
}

/// `P(C occupied | viewpoint)` for the cube `centre ± half` (§5.4), from two
/// things the viewpoint says about C:
/// - `H`, how surely a surface lies inside C: the maximum, over the beams whose
///   centre line crosses C, of their chord's first-hit probability `P(a ≤ λ ≤ b)`
///   (a cell no centre line crosses takes the beams of the bin holding its
///   centre, with its whole range extent as the chord);
/// - `F`, the share of C seen in front of the surface: the mean over C's eight
///   corners of `P(λ > ρ)` against the nearest surface of the corner's bin.
///
/// `None`: no beam informs the cell.
pub fn cell_occupancy(
    grid: &LocalGrid,
    model: &CellModel,
    centre: &Vector3,
    half: f64,
    bins: &BinBox,
) -> Option<f64> {
    let max_range = grid.max_range;
    let inside = |beam, a: f64, b: f64| {
        model.split(beam, a, b, max_range).1 * origin_step(0.5 * (a + b), beam.sigma_origin)
    };
    // A beam whose surface band misses the ball's range interval (which
    // holds every chord through C) says "no surface inside" exactly: `split`
    // returns 0 inside for it. Only the others need their chord; the rest
    // matter only for whether any centre line crosses C at all.
    let (lo, hi) = bins.range;
    let margin = 1e-9 * (1.0 + hi);
    let may_hold = |beam: &Beam| {
        beam.range.is_finite()
            && beam.band_start(max_range) <= hi + margin
            && beam.reach(max_range) >= lo - margin
    };
    let mut hit = 0.0f64;
    let mut crossed = false;
    let mut others = false;
    for a in bins.azimuth.0..=bins.azimuth.1 {
        for e in bins.elevation.0..=bins.elevation.1 {
            let (beams, inverse) = grid.bin_beams(a, e);
            if beams.is_empty() {
                continue;
            }
            // The bin's bands (and its nearest surface's) span [near, far]:
            // when that misses [lo, hi], none of its beams may hold it.
            let bin = grid.bin_summary(a, e);
            if bin.near > hi + margin || bin.far < lo - margin {
                others = true;
                continue;
            }
            for (beam, inv) in beams.iter().zip(inverse) {
                if !may_hold(beam) {
                    others = true;
                    continue;
                }
                if let Some((t0, t1)) = ray_box(&grid.origin, inv, centre, half) {
                    crossed = true;
                    hit = hit.max(inside(beam, t0, t1));
                }
            }
        }
    }
    if !crossed {
        if let Some((a, e)) = grid.bin_of(centre) {
            let centre_beams = grid.bin_beams(a, e).0;
            // The fallback (no centre line crosses C) can only raise `hit`
            // through a beam that may hold the surface; decide whether it
            // applies only then.
            if centre_beams.iter().any(may_hold)
                && !(others && any_crosses(grid, centre, half, bins, &may_hold))
            {
                for beam in centre_beams {
                    hit = hit.max(inside(beam, lo, hi));
                }
            }
        }
    }
    combine(grid, model, centre, half, hit)
}

/// The viewpoint's verdict on C from `hit` (H): with `F` the mean over C's
/// eight corners of `P(λ > ρ)` against the nearest surface of the corner's
/// bin, `view_occupancy(H, F)`; `p_hi` outright when H reaches it.
pub(crate) fn combine(
    grid: &LocalGrid,
    model: &CellModel,
    centre: &Vector3,
    half: f64,
    hit: f64,
) -> Option<f64> {
    if hit >= model.p_hi {
        // A surface surely inside: the share seen free changes nothing.
        return Some(model.p_hi);
    }
    let mut free = 0.0;
    for corner in 0..8u8 {
        let sign = |axis: u8| if corner >> axis & 1 == 1 { half } else { -half };
        let point = centre + Vector3::new(sign(0), sign(1), sign(2));
        let Some((a, e)) = grid.bin_of(&point) else {
            continue;
        };
        if let Some(surface) = grid.bin_surface(a, e) {
            free += model.free_at(surface, (point - grid.origin).norm(), grid.max_range);
        }
    }
    free /= 8.0;
    (hit > 0.0 || free > 0.0).then(|| model.view_occupancy(hit, free))
}
