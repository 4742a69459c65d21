//! Merging a viewpoint's local grid into the global octree by intersection
//! search (docs/math.md §5.3) with the cell-occupancy model (§5.4): descend
//! only into octree cells that meet the grid's beams; update a whole cell at
//! once where every beam certifies all of it free; at the finest level combine
//! the chance that a surface lies inside the cell (looked up in the grid's
//! [`SurfaceCells`]) with the share of the cell seen in front of the surface,
//! and fuse in log-odds.

use super::chord::{ray_box, Beam, CellModel};
use super::octree::{Clamp, Key, Octree, DEPTH};
use super::opdf::logit;
use super::spherical::{BinBox, LocalGrid};
use super::surface_cells::{chord_surface, SurfaceCells};
use crate::geometry::Vector3;
use rayon::prelude::*;

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

/// The smallest edge (m) of the nodes the merge's search is split at: one
/// task per node, many tasks, each worth one.
const TASK_EDGE: f64 = 0.1;

/// The depth of the task nodes at `resolution`: the deepest whose edge
/// reaches [`TASK_EDGE`], at least [`CORNER_BLOCK`] levels above the finest
/// (a task holds whole corner caches).
fn task_depth(resolution: f64) -> u8 {
    let mut depth = DEPTH - CORNER_BLOCK;
    while depth > 1 && resolution * f64::from(1u32 << (DEPTH - depth)) < TASK_EDGE {
        depth -= 1;
    }
    depth
}

/// Fuses `grid` into `tree`. The search runs on the current rayon pool, one
/// task per node of [`task_depth`]; its updates are applied afterwards in
/// depth-first order, so the tree is the same whatever the thread count.
pub fn merge(tree: &mut Octree, grid: &LocalGrid, options: &MergeOptions) -> MergeStats {
    let surfaces = SurfaceCells::new(grid, &options.model, tree);
    merge_with(tree, grid, &surfaces, options)
}

/// [`merge`] with the grid's [`SurfaceCells`] built beforehand (on a tree
/// of the same resolution), e.g. while the previous grid is merged.
pub fn merge_with(
    tree: &mut Octree,
    grid: &LocalGrid,
    surfaces: &SurfaceCells,
    options: &MergeOptions,
) -> MergeStats {
    let mut plan = MergePlan::default();
    plan.search(tree, grid, surfaces, options);
    plan.apply(tree, options.clamp);
    plan.stats
}

/// The changes a merge makes to the tree, found from the tree's geometry
/// alone (its resolution; not its contents), so that a grid can be searched
/// while earlier ones are applied: [`MergePlan::search`], then
/// [`MergePlan::apply`]. Its memory is reused from grid to grid.
#[derive(Default)]
pub struct MergePlan {
    /// `(Morton code, depth, delta)` in depth-first order.
    changes: Vec<(u64, u8, f32)>,
    /// The search's counters.
    pub stats: MergeStats,
}

impl MergePlan {
    /// Searches `grid` (with its `surfaces`) on the cells of `geometry`'s
    /// resolution, one rayon task per node of [`task_depth`]; the changes
    /// are kept in depth-first order, so the tree they make is the same
    /// whatever the thread count.
    pub fn search(
        &mut self,
        geometry: &Octree,
        grid: &LocalGrid,
        surfaces: &SurfaceCells,
        options: &MergeOptions,
    ) {
        self.changes.clear();
        self.stats = MergeStats::default();
        if grid.beam_count() == 0 {
            return;
        }
        let planner = Planner {
            tree: geometry,
            grid,
            surfaces,
            options,
            task_depth: task_depth(geometry.resolution()),
        };
        let mut skeleton = Plan::default();
        planner.search(Key([0, 0, 0]), 0, None, &mut skeleton, (true, true));
        let tasks: Vec<Plan> = skeleton
            .tasks
            .par_iter()
            .map(|&key| {
                let mut plan = Plan::default();
                planner.search(key, planner.task_depth, None, &mut plan, (false, true));
                plan
            })
            .collect();
        self.stats = skeleton.stats;
        let mut tasks = tasks.into_iter();
        // The search's order is depth first: the tree takes the changes in
        // one walk.
        self.changes.reserve(skeleton.updates.len());
        for update in &skeleton.updates {
            match *update {
                Update::Task => {
                    let task = tasks.next().expect("one plan per task");
                    self.stats.add(&task.stats);
                    self.changes.extend(task.updates.iter().map(Update::change));
                }
                ref u => self.changes.push(u.change()),
            }
        }
    }

    /// Applies the changes found by the last [`MergePlan::search`] to
    /// `tree` (of the searched resolution), with the map-level `clamp`.
    pub fn apply(&self, tree: &mut Octree, clamp: Clamp) {
        tree.update_depth_first(self.changes.iter().copied(), clamp);
    }
}

impl MergeStats {
    fn add(&mut self, other: &MergeStats) {
        self.visited += other.visited;
        self.coarse_updates += other.coarse_updates;
        self.fine_updates += other.fine_updates;
    }
}

/// One change the merge makes to the tree, in search order.
#[derive(Clone, Copy, Debug)]
enum Update {
    /// Add `delta` to every cell of the node at `depth` containing `key`.
    Region { key: Key, depth: u8, delta: f32 },
    /// Add `delta` to the finest cell `key`.
    Cell { key: Key, delta: f32 },
    /// The updates of the next task, in its place.
    Task,
}

impl Update {
    /// `(Morton code, depth, delta)` for [`Octree::update_depth_first`].
    fn change(&self) -> (u64, u8, f32) {
        match *self {
            Update::Region { key, depth, delta } => (key.morton(), depth, delta),
            Update::Cell { key, delta } => (key.morton(), DEPTH, delta),
            Update::Task => unreachable!("tasks are replaced by their updates"),
        }
    }
}

/// What a search found: its updates in depth-first order and, above the
/// task depth, the nodes left to tasks.
#[derive(Default)]
struct Plan {
    updates: Vec<Update>,
    tasks: Vec<Key>,
    stats: MergeStats,
}

/// The read-only search of the merge: which cells the grid informs and how.
struct Planner<'a> {
    tree: &'a Octree,
    grid: &'a LocalGrid,
    surfaces: &'a SurfaceCells,
    options: &'a MergeOptions,
    task_depth: u8,
}

impl Planner<'_> {
    /// Searches the node at `depth` containing `key`; with `split`, leaves
    /// the nodes at the task depth to tasks. `bands`: whether some beam's
    /// surface band may reach the node (false only when its parent's bins
    /// showed none can).
    fn search(
        &self,
        key: Key,
        depth: u8,
        corners: Option<&mut CornerCache>,
        plan: &mut Plan,
        (split, bands): (bool, bool),
    ) {
        plan.stats.visited += 1;
        let centre = self.tree.center(&key, depth).coords;
        let half = self.tree.node_size(depth) * 0.5;
        if depth == DEPTH {
            let corners = corners.expect("finest cells come with their block's corner cache");
            self.finest(key, &centre, half, corners, plan, bands);
            return;
        }
        let stats = &mut plan.stats;
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
            let delta = self.options.model.free_log_odds();
            plan.updates.push(Update::Region { key, depth, delta });
            stats.coarse_updates += 1;
            return;
        }
        // No band of the ball's bins reaches its range: none reaches a
        // child's (inside it; twice the rounding margin of `may_hold`).
        let bands = bands && bins.range.1 + 2e-9 * (1.0 + bins.range.1) >= s.near;
        // The finest cells of a block share their corners.
        let mut own = (depth == DEPTH - CORNER_BLOCK).then(|| CornerCache::new(key));
        let mut corners = own.as_mut().or(corners);
        let bit = 15 - depth as u32;
        for child in 0..8u16 {
            let mut k = key;
            for (axis, kk) in k.0.iter_mut().enumerate() {
                *kk |= ((child >> axis) & 1) << bit;
            }
            if split && depth + 1 == self.task_depth {
                plan.tasks.push(k);
                plan.updates.push(Update::Task);
            } else {
                self.search(k, depth + 1, corners.as_deref_mut(), plan, (split, bands));
            }
        }
    }
}

impl Planner<'_> {
    /// The finest cell `key`: the cell model's value (§5.4) from `H` (the
    /// index, or [`surface_off_bands`]) and the free share of its corners.
    /// No ball test comes first: where the node tests above would find no
    /// beam, every corner's bin is empty or beyond reach and `H` is 0 (no
    /// update); where they would certify it free, every corner is free and
    /// `H` is 0 (`p_lo`), so the evaluation gives what they give.
    fn finest(
        &self,
        key: Key,
        centre: &Vector3,
        half: f64,
        corners: &mut CornerCache,
        plan: &mut Plan,
        bands: bool,
    ) {
        let model = &self.options.model;
        let hit = match self.surfaces.get(&key) {
            Some(hit) => hit,
            None if bands => surface_off_bands(self.grid, model, centre, half),
            None => 0.0,
        };
        let offset = corners.offset(&key);
        let p = combine(model, hit, |i| {
            let [x, y, z] = corner_offset(i);
            corners.free(
                self.tree,
                self.grid,
                model,
                [offset[0] + x, offset[1] + y, offset[2] + z],
            )
        });
        if let Some(p) = p {
            let delta = logit(p) as f32;
            if delta.abs() >= NEUTRAL {
                plan.updates.push(Update::Cell { key, delta });
                plan.stats.fine_updates += 1;
            }
        }
    }
}

/// The corner offsets (0 or 1 per axis) of corner `i`: bit 0 of `i` is x,
/// bit 1 is y, bit 2 is z.
#[inline]
fn corner_offset(i: usize) -> [u16; 3] {
    [(i & 1) as u16, (i >> 1 & 1) as u16, (i >> 2 & 1) as u16]
}

/// The levels above the finest at which a corner cache starts: its block of
/// `2^k` finest cells a side shares `(2^k + 1)³` lattice points.
const CORNER_BLOCK: u8 = 3;

/// Lattice points a side of a corner block.
const LATTICE: usize = (1 << CORNER_BLOCK) + 1;

/// The corner values ([`corner_free`]) of the finest cells of one block (a
/// node [`CORNER_BLOCK`] levels above the finest): its lattice points, each
/// evaluated at most once, whichever cells share it.
struct CornerCache {
    base: Key,
    free: [f64; LATTICE * LATTICE * LATTICE],
}

impl CornerCache {
    fn new(base: Key) -> Self {
        Self {
            base,
            free: [f64::NAN; LATTICE * LATTICE * LATTICE],
        }
    }

    /// A cell's lower corner as lattice offsets from the base.
    fn offset(&self, key: &Key) -> [u16; 3] {
        std::array::from_fn(|a| key.0[a] - self.base.0[a])
    }

    fn free(&mut self, tree: &Octree, grid: &LocalGrid, model: &CellModel, at: [u16; 3]) -> f64 {
        let [x, y, z] = at.map(usize::from);
        let slot = &mut self.free[(z * LATTICE + y) * LATTICE + x];
        if slot.is_nan() {
            *slot = corner_free(grid, model, &tree.lattice_point(&self.base, at).coords);
        }
        *slot
    }
}

/// A finest cell as the cell model sees it: centre, half edge and corners
/// (corner `i` as in [`corner_offset`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// The cube's centre (scene frame).
    pub centre: Vector3,
    /// Half its edge.
    pub half: f64,
    /// Its eight corners.
    pub corners: [Vector3; 8],
}

impl Cell {
    /// The tree's finest cell `key`, with lattice corners as the merge uses.
    pub fn of(tree: &Octree, key: &Key) -> Self {
        Self {
            centre: tree.center(key, DEPTH).coords,
            half: tree.node_size(DEPTH) * 0.5,
            corners: std::array::from_fn(|i| tree.lattice_point(key, corner_offset(i)).coords),
        }
    }

    /// The cube `centre ± half`.
    pub fn around(centre: Vector3, half: f64) -> Self {
        Self {
            centre,
            half,
            corners: std::array::from_fn(|i| {
                let [x, y, z] = corner_offset(i).map(|o| if o == 1 { half } else { -half });
                centre + Vector3::new(x, y, z)
            }),
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
    bin_box_beams(grid, bins)
        .any(|(beam, inv)| !may_hold(beam) && ray_box(&grid.origin, inv, centre, half).is_some())
}

/// `P(C occupied | viewpoint)` for the finest cell `cell` (§5.4), from two
/// things the viewpoint says about C:
/// - `H` ([`surface_inside`]), how surely a surface lies inside C;
/// - `F`, the share of C seen in front of the surface: the mean over C's eight
///   corners of `P(λ > ρ)` against the nearest surface of the corner's bin.
///
/// `None`: no beam informs the cell.
pub fn cell_occupancy(
    grid: &LocalGrid,
    model: &CellModel,
    cell: &Cell,
    bins: &BinBox,
) -> Option<f64> {
    let (centre, half) = (&cell.centre, cell.half);
    let mut hit = surface_inside(grid, model, centre, half, bins);
    // The grid's surface samples (all of them: this is the reference)
    // count as beams whose centre lines cross C; a cell they give a surface
    // is one some line crosses, so the fallback for a cell between lines
    // does not apply to it.
    let (samples, inverse) = grid.samples();
    let sampled = samples
        .iter()
        .zip(inverse)
        .filter_map(|(s, inv)| {
            let (a, b) = ray_box(&grid.origin, inv, centre, half)?;
            Some(chord_surface(model, s, a, b, grid.max_range))
        })
        .fold(0.0, f64::max);
    if sampled > 0.0 {
        let crossed = bin_box_beams(grid, bins)
            .any(|(_, inv)| ray_box(&grid.origin, inv, centre, half).is_some());
        hit = if crossed { hit.max(sampled) } else { sampled };
    }
    combine(model, hit, |i| corner_free(grid, model, &cell.corners[i]))
}

/// The beams of the bins of `bins`, with their inverse directions.
fn bin_box_beams<'a>(
    grid: &'a LocalGrid,
    bins: &BinBox,
) -> impl Iterator<Item = (&'a Beam, &'a Vector3)> + 'a {
    let ((a0, a1), (e0, e1)) = (bins.azimuth, bins.elevation);
    (a0..=a1)
        .flat_map(move |a| (e0..=e1).map(move |e| grid.bin_beams(a, e)))
        .flat_map(|(beams, inverse)| beams.iter().zip(inverse))
}

/// `H` for the cube `centre ± half`: the maximum, over the beams whose centre
/// line crosses C, of their chord's first-hit probability `P(a ≤ λ ≤ b)` (a
/// cell no centre line crosses takes the beams of the bin holding its centre,
/// with its whole range extent as the chord). The search stops once `H`
/// reaches `p_hi`, where [`combine`] stops looking.
pub fn surface_inside(
    grid: &LocalGrid,
    model: &CellModel,
    centre: &Vector3,
    half: f64,
    bins: &BinBox,
) -> f64 {
    let max_range = grid.max_range;
    let inside = |beam, a: f64, b: f64| chord_surface(model, beam, a, b, max_range);
    // A beam whose surface band misses the ball's range interval (which
    // holds every chord through C) says "no surface inside" exactly: `split`
    // returns 0 inside for it. Only the others need their chord; the rest
    // matter only for whether any centre line crosses C at all.
    let (lo, hi) = bins.range;
    let margin = 1e-9 * (1.0 + hi);
    let may_hold = |beam: &Beam| may_hold(beam, bins, max_range);
    let mut hit = 0.0f64;
    let mut crossed = false;
    let mut others = false;
    // One bin's beams into `hit`; true once `hit` reaches p_hi, where
    // `combine` gives p_hi whatever else is found.
    let mut visit = |a: usize, e: usize| {
        let (beams, inverse) = grid.bin_beams(a, e);
        if beams.is_empty() {
            return false;
        }
        // The bin's bands (and its nearest surface's) span [near, far]:
        // when that misses [lo, hi], none of its beams may hold it.
        let bin = grid.bin_summary(a, e);
        if bin.near > hi + margin || bin.far < lo - margin {
            others = true;
            return false;
        }
        for (beam, inv) in beams.iter().zip(inverse) {
            if !may_hold(beam) {
                others = true;
                continue;
            }
            if let Some((t0, t1)) = ray_box(&grid.origin, inv, centre, half) {
                crossed = true;
                hit = hit.max(inside(beam, t0, t1));
                if hit >= model.p_hi {
                    return true;
                }
            }
        }
        false
    };
    // The centre's bin first: a cell holding the surface usually gets its
    // p_hi there. Visiting it again below changes nothing (max, flags).
    if let Some((a, e)) = bins.centre {
        if visit(a, e) {
            return hit;
        }
    }
    // Tiles of 4 × 4 bins (pyramid level 2) whose bands all miss [lo, hi]
    // are passed over whole. `others_in_tiles` is then set if the tile holds
    // any beam, inside the box or not: it only decides whether `any_crosses`
    // is asked, which answers exactly either way.
    let level = grid.tile_level(2);
    let ((a0, a1), (e0, e1)) = (bins.azimuth, bins.elevation);
    let mut others_in_tiles = false;
    for ta in a0 >> level..=a1 >> level {
        for te in e0 >> level..=e1 >> level {
            let tile = grid.tile_summary(level, ta, te);
            if tile.filled == 0 {
                continue;
            }
            if tile.near > hi + margin || tile.far < lo - margin {
                others_in_tiles = true;
                continue;
            }
            for a in a0.max(ta << level)..=a1.min(((ta + 1) << level) - 1) {
                for e in e0.max(te << level)..=e1.min(((te + 1) << level) - 1) {
                    if visit(a, e) {
                        return hit;
                    }
                }
            }
        }
    }
    if !crossed {
        if let Some((a, e)) = bins.centre {
            let centre_beams = grid.bin_beams(a, e).0;
            // The fallback (no centre line crosses C) can only raise `hit`
            // through a beam that may hold the surface; decide whether it
            // applies only then.
            if centre_beams.iter().any(may_hold)
                && !((others || others_in_tiles)
                    && any_crosses(grid, centre, half, bins, &may_hold))
            {
                for beam in centre_beams {
                    hit = hit.max(inside(beam, lo, hi));
                }
            }
        }
    }
    hit
}

/// Whether `beam`'s surface band reaches the range interval of the ball
/// `bins` was found for (with a rounding margin): only such a beam can put a
/// surface inside a cell of that ball.
#[inline]
fn may_hold(beam: &Beam, bins: &BinBox, max_range: f64) -> bool {
    may_hold_in(beam, bins.range, max_range)
}

/// [`may_hold`] for the range interval `(lo, hi)`.
#[inline]
fn may_hold_in(beam: &Beam, (lo, hi): (f64, f64), max_range: f64) -> bool {
    let margin = 1e-9 * (1.0 + hi);
    beam.range.is_finite()
        && beam.band_start(max_range) <= hi + margin
        && beam.reach(max_range) >= lo - margin
}

/// [`surface_inside`] for a cell that no beam's surface band touches (it is
/// not in the [`SurfaceCells`]): every beam crossing C gives 0, so `H` is 0
/// unless no centre line crosses C at all and a beam of C's centre bin may
/// hold the surface (its fallback), which the full search then answers. Only
/// then are the bins of C's ball looked up.
pub(crate) fn surface_off_bands(
    grid: &LocalGrid,
    model: &CellModel,
    centre: &Vector3,
    half: f64,
) -> f64 {
    let radius = half * 3f64.sqrt();
    let Some((a, e)) = grid.bin_of(centre) else {
        return 0.0;
    };
    // The ball's range interval, as `ball_bins` gives it.
    let dist = grid.grid_offset(centre).norm();
    let range = ((dist - radius).max(0.0), dist + radius);
    let (beams, inverse) = grid.bin_beams(a, e);
    if !beams.iter().any(|b| may_hold_in(b, range, grid.max_range))
        || inverse
            .iter()
            .any(|inv| ray_box(&grid.origin, inv, centre, half).is_some())
    {
        return 0.0;
    }
    grid.ball_bins(centre, radius)
        .map_or(0.0, |bins| surface_inside(grid, model, centre, half, &bins))
}

/// The viewpoint's verdict on C from `hit` (H) and the free share of its
/// corners (`corner_free(i)` for corner `i`, summed in corner order): with `F`
/// their mean, `view_occupancy(H, F)`; `p_hi` outright when H reaches it.
pub(crate) fn combine(
    model: &CellModel,
    hit: f64,
    mut corner_free: impl FnMut(usize) -> f64,
) -> Option<f64> {
    if hit >= model.p_hi {
        // A surface surely inside: the share seen free changes nothing.
        return Some(model.p_hi);
    }
    let mut free = 0.0;
    for corner in 0..8 {
        free += corner_free(corner);
    }
    free /= 8.0;
    (hit > 0.0 || free > 0.0).then(|| model.view_occupancy(hit, free))
}

/// `P(λ > ρ)` at scene point `point` against the nearest surface of its bin
/// (0 outside the grid or in a bin without a surface).
pub(crate) fn corner_free(grid: &LocalGrid, model: &CellModel, point: &Vector3) -> f64 {
    let Some((a, e)) = grid.bin_of(point) else {
        return 0.0;
    };
    grid.bin_surface(a, e).map_or(0.0, |surface| {
        model.free_at(surface, (point - grid.origin).norm(), grid.max_range)
    })
}
