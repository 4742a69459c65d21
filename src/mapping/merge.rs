//! Merging a viewpoint's local grid into the global octree by intersection
//! search (docs/math.md §5.3) with the cell-occupancy model (§5.4): descend
//! only into octree cells that meet the grid's beams; update a whole cell at
//! once where every beam certifies all of it free; at the finest level combine
//! the chance that a surface lies inside the cell (looked up in the grid's
//! [`SurfaceCells`]) with the share of the cell seen in front of the surface,
//! and fuse in log-odds.

use super::chord::CellModel;
use super::octree::{Clamp, Key, Octree, DEPTH};
use super::opdf::logit;
use super::spherical::LocalGrid;
use super::surface_cells::{SurfaceBlock, SurfaceCells, BLOCK_BITS};
use cell::corner_offset;
pub use cell::{cell_occupancy, surface_inside, Cell};
pub(crate) use cell::{combine, corner_free, surface_off_bands};
use rayon::prelude::*;

mod cell;

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
/// reaches [`TASK_EDGE`], at least [`LATTICE_BLOCK`] levels above the finest
/// (a task holds whole corner caches).
fn task_depth(resolution: f64) -> u8 {
    let mut depth = DEPTH - LATTICE_BLOCK;
    while depth > 1 && resolution * f64::from(1u32 << (DEPTH - depth)) < TASK_EDGE {
        depth -= 1;
    }
    depth
}

/// Fuses `grid` into `tree`. The search runs on the current rayon pool, one
/// task per node of `task_depth`; its updates are applied afterwards in
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
    /// resolution, one rayon task per node of `task_depth`; the changes
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
            free_log_odds: options.model.free_log_odds(),
            crossed_within: crossed_within(grid, geometry.node_size(DEPTH) * 0.5),
        };
        let mut skeleton = Plan::default();
        let mut corners = CornerCache::default();
        planner.search(Key([0, 0, 0]), 0, &mut corners, &mut skeleton, (true, true));
        let tasks: Vec<Plan> = skeleton
            .tasks
            .par_iter()
            .map_init(CornerCache::default, |corners, &key| {
                let mut plan = Plan::default();
                planner.search(key, planner.task_depth, corners, &mut plan, (false, true));
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
    /// Add `delta` to the finest cell of Morton code `code`.
    Cell { code: u64, delta: f32 },
    /// The updates of the next task, in its place.
    Task,
}

impl Update {
    /// `(Morton code, depth, delta)` for [`Octree::update_depth_first`].
    fn change(&self) -> (u64, u8, f32) {
        match *self {
            Update::Region { key, depth, delta } => (key.morton(), depth, delta),
            Update::Cell { code, delta } => (code, DEPTH, delta),
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
    /// [`CellModel::free_log_odds`] of the options' model.
    free_log_odds: f32,
    /// [`crossed_within`] of the grid at the finest cells.
    crossed_within: f64,
}

/// The range (m) within which every beam of a finest cell's centre bin
/// surely crosses the cell (cells of half edge `half`).
///
/// Two directions in one bin, at most `Δa` apart in azimuth and `Δe` in
/// elevation, are an angle `d` apart with `sin²(d/2) = sin²(Δe/2) +
/// cos e₁ cos e₂ sin²(Δa/2) ≤ (Δa² + Δe²)/4` (the haversine formula). So a
/// beam of the bin of a cell's centre `c` passes within `|c − o| sin d ≤
/// |c − o| 2 sin(d/2) ≤ |c − o| hypot(Δa, Δe)` of `c`: inside the cube's
/// inscribed ball while that is below `half`. A millionth is taken off for
/// the bins' rounding at their edges.
fn crossed_within(grid: &LocalGrid, half: f64) -> f64 {
    let angle = grid.azimuth.step.hypot(grid.elevation.step);
    half * (1.0 - 1e-6) / (angle * (1.0 + 1e-6))
}

impl<'a> Planner<'a> {
    /// Searches the node at `depth` (above the finest) containing `key`;
    /// with `split`, leaves the nodes at the task depth to tasks. `bands`:
    /// whether the surface band of some beam with a return may reach the
    /// node (false only when an ancestor's bins showed none can).
    fn search(
        &self,
        key: Key,
        depth: u8,
        corners: &mut CornerCache<'a>,
        plan: &mut Plan,
        (split, bands): (bool, bool),
    ) {
        plan.stats.visited += 1;
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
            let delta = self.free_log_odds;
            plan.updates.push(Update::Region { key, depth, delta });
            plan.stats.coarse_updates += 1;
            return;
        }
        // No band of a returning beam of the ball's bins reaches its range:
        // none reaches a child's (inside it; twice the rounding margin of
        // `may_hold`).
        let bands = bands && bins.range.1 + 2e-9 * (1.0 + bins.range.1) >= s.hit_near;
        // The finest cells of a lattice block share their corners, those of
        // an index block their cells of the surface index.
        if depth == DEPTH - LATTICE_BLOCK {
            corners.start(key);
        }
        if depth == DEPTH - INDEX_BLOCK {
            corners.surfaces = self.surfaces.block(&key);
        }
        if depth == DEPTH - 1 {
            // The finest cells, in child order, without a call of their own.
            plan.stats.visited += 8;
            // Within `crossed_within` a child's centre bin is empty or its
            // beams cross the child: either way `surface_off_bands` gives
            // its first answer, `H = 0`, so its bin need not be looked up.
            let bands = bands && bins.range.1 >= self.crossed_within;
            // A child's Morton code is its parent's with the child index as
            // its last three bits.
            let code = key.morton();
            for child in 0..8u16 {
                let k = key.child(depth, child);
                self.finest(k, code | u64::from(child), corners, plan, bands);
            }
            return;
        }
        for child in 0..8u16 {
            let k = key.child(depth, child);
            if split && depth + 1 == self.task_depth {
                plan.tasks.push(k);
                plan.updates.push(Update::Task);
            } else {
                self.search(k, depth + 1, corners, plan, (split, bands));
            }
        }
    }

    /// The finest cell `key` (Morton code `code`): the cell model's value
    /// (§5.4) from `H` (the index, or [`surface_off_bands`]) and the free
    /// share of its corners; `bands` false where the parent showed that
    /// [`surface_off_bands`] gives 0 (no band reaches, or the cell is surely
    /// crossed). No ball test comes first: where the node tests above would
    /// find no beam, every corner's bin is empty or beyond reach and `H` is 0
    /// (no update); where they would certify it free, every corner is free
    /// and `H` is 0 (`p_lo`), so the evaluation gives what they give.
    fn finest(
        &self,
        key: Key,
        code: u64,
        corners: &mut CornerCache<'a>,
        plan: &mut Plan,
        bands: bool,
    ) {
        let model = &self.options.model;
        let hit = match corners.surfaces.get(&key) {
            Some(hit) => hit,
            None if bands => {
                let centre = self.tree.center(&key, DEPTH).coords;
                let half = self.tree.node_size(DEPTH) * 0.5;
                surface_off_bands(self.grid, model, &centre, half)
            }
            None => 0.0,
        };
        let cell = corners.offset(&key);
        let p = combine(model, hit, |i| {
            corners.free(self.tree, self.grid, model, cell, i)
        });
        if let Some(p) = p {
            // A free cell, the most common verdict, skips the logarithm.
            let delta = if p == model.p_lo {
                self.free_log_odds
            } else {
                logit(p) as f32
            };
            if delta.abs() >= NEUTRAL {
                plan.updates.push(Update::Cell { code, delta });
                plan.stats.fine_updates += 1;
            }
        }
    }
}

/// The levels above the finest of a lattice block: its `2^k` finest cells a
/// side share `(2^k + 1)³` lattice points, each evaluated at most once.
const LATTICE_BLOCK: u8 = 5;

/// Lattice points a side of a lattice block.
const LATTICE: usize = (1 << LATTICE_BLOCK) + 1;

/// The levels above the finest of the surface index's blocks
/// ([`SurfaceCells::block`]): one look-up serves a block's cells.
const INDEX_BLOCK: u8 = BLOCK_BITS as u8;

// An index block lies inside one lattice block.
const _: () = assert!(INDEX_BLOCK <= LATTICE_BLOCK);

/// Corner `i`'s place in a corner cache ([`corner_offset`]) from its
/// cell's lower corner's.
const CORNER_SLOTS: [usize; 8] = {
    let mut slots = [0; 8];
    let mut i = 0;
    while i < 8 {
        slots[i] = (i & 1) + (i >> 1 & 1) * LATTICE + (i >> 2 & 1) * LATTICE * LATTICE;
        i += 1;
    }
    slots
};

/// What the finest cells of a block share while the search is in it: the
/// values ([`corner_free`]) of the lattice points of its lattice block,
/// each evaluated at most once whichever cells share it, and its index
/// block's cells of the surface index, found once. One cache serves block
/// after block: a point's value belongs to the current lattice block only
/// when its stamp is the block's, so starting a block clears nothing.
struct CornerCache<'a> {
    base: Key,
    surfaces: SurfaceBlock<'a>,
    block: u32,
    /// Per lattice point, `(value, stamp)`.
    points: Vec<(f64, u32)>,
}

impl Default for CornerCache<'_> {
    fn default() -> Self {
        Self {
            base: Key([0, 0, 0]),
            surfaces: SurfaceBlock::NONE,
            block: 0,
            points: Vec::new(),
        }
    }
}

impl CornerCache<'_> {
    /// Starts the lattice block whose lowest cell is `base`: no value known.
    fn start(&mut self, base: Key) {
        self.base = base;
        self.block = self.block.wrapping_add(1);
        if self.points.is_empty() {
            // The first block (the search above the tasks needs none).
            self.points = vec![(0.0, 0); LATTICE * LATTICE * LATTICE];
        }
        if self.block == 0 {
            // The stamps wrapped (once in 2^32 blocks): clear them.
            self.points.fill((0.0, 0));
            self.block = 1;
        }
    }

    /// A cell's lower corner as lattice offsets from the base.
    fn offset(&self, key: &Key) -> [u16; 3] {
        std::array::from_fn(|a| key.0[a] - self.base.0[a])
    }

    /// The value of corner `corner` ([`corner_offset`]) of the cell whose
    /// lower corner is lattice point `cell`.
    #[inline]
    fn free(
        &mut self,
        tree: &Octree,
        grid: &LocalGrid,
        model: &CellModel,
        cell: [u16; 3],
        corner: usize,
    ) -> f64 {
        let [x, y, z] = cell.map(usize::from);
        let slot = (z * LATTICE + y) * LATTICE + x + CORNER_SLOTS[corner];
        let (value, stamp) = self.points[slot];
        if stamp == self.block {
            return value;
        }
        let [dx, dy, dz] = corner_offset(corner);
        let at = [cell[0] + dx, cell[1] + dy, cell[2] + dz];
        let value = corner_free(grid, model, &tree.lattice_point(&self.base, at).coords);
        self.points[slot] = (value, self.block);
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Matrix3, Vector3};
    use crate::mapping::chord::ray_box;
    use crate::mapping::spherical::Axis;
    use rand::{Rng, SeedableRng};

    /// Every beam of the bin of a cell's centre crosses the cell when the
    /// centre lies within `crossed_within`: beams and centres drawn in one
    /// bin, at its corners (the farthest apart) or anywhere, with cells of
    /// 5 mm to 5 cm at up to the bound's range.
    #[test]
    fn a_beam_of_a_cells_centre_bin_crosses_it_within_crossed_within() {
        let step = 0.25f64.to_radians();
        let axis = |count: usize| Axis {
            start: -(count as f64) * step / 2.0,
            step,
            count,
        };
        let origin = Vector3::new(0.1, -0.2, 0.3);
        let grid = LocalGrid::new(
            origin,
            Matrix3::identity(),
            axis(360),
            axis(240),
            3.0,
            &[],
            &Matrix3::zeros(),
        );
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let fraction = |rng: &mut rand_chacha::ChaCha8Rng| match rng.random_range(0..3) {
            0 => 1e-4,
            1 => 1.0 - 1e-4,
            _ => rng.random::<f64>(),
        };
        let mut checked = 0;
        for _ in 0..4000 {
            let (a, e) = (rng.random_range(0..360), rng.random_range(0..240));
            let direction = |rng: &mut rand_chacha::ChaCha8Rng| {
                let az = grid.azimuth.start + (a as f64 + fraction(rng)) * step;
                let el = grid.elevation.start + (e as f64 + fraction(rng)) * step;
                Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
            };
            let (beam, towards) = (direction(&mut rng), direction(&mut rng));
            let half = [0.0025, 0.005, 0.01, 0.025][rng.random_range(0..4)];
            let range = crossed_within(&grid, half) * rng.random_range(0.5..1.0);
            let centre = origin + towards * range;
            if grid.bin_of(&(origin + beam)) != Some((a, e)) || grid.bin_of(&centre) != Some((a, e))
            {
                continue;
            }
            let inverse = beam.map(|c| 1.0 / c);
            assert!(
                ray_box(&origin, &inverse, &centre, half).is_some(),
                "a beam of bin ({a}, {e}) misses the cell of half edge {half} at {range} m"
            );
            checked += 1;
        }
        assert!(checked > 3000, "{checked} pairs checked");
    }
}
