//! The shared pose error, accounted for once on the fused map
//! (docs/math.md §6.6).
//!
//! Scene registration (T_sw) and hand-eye (T_cr) errors are drawn once per
//! run: given them, the viewpoints' errors are independent and their local
//! grids fuse in log-odds without double counting. The fused map `P₀` is
//! then the map conditioned on the shared error being zero; the shared error
//! moves it by a displacement `d(x) ≈ J_shared(x) ξ`, `ξ ~ N(0, Γ_shared)`,
//! so the map a robot should use is the expectation
//!
//! `P(x) = E_d[P₀(x − d)]`, `d ~ N(0, Σ(x))`, `Σ(x) = J_shared Γ_shared J_sharedᵀ`,
//!
//! a convolution of the fused probabilities with a Gaussian whose covariance
//! varies slowly over the map (one per block of 8³ cells). Only known cells
//! enter the average and only known cells are written: an unobserved cell
//! stays unknown.

use super::octree::{Clamp, Key, Leaf, Octree, DEPTH};
use super::opdf::{logit, probability};
use crate::geometry::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

/// Cells per block edge: one kernel per block.
const BLOCK: i64 = 8;
/// At most this many kernel samples per axis side (the kernel is strided
/// beyond it, so a wide σ costs no more than a narrow one).
const MAX_HALF: i64 = 6;
/// A slab of the source box (a block's layers and the halo) is held densely
/// in one buffer of at most this many cells (256 MB).
const MAX_SLAB_CELLS: i64 = 1 << 26;

/// What [`expect_over_shared_motion`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SharedMotionStats {
    /// Known cells whose value was recomputed.
    pub evaluated: usize,
    /// Cells whose value changed.
    pub changed: usize,
    /// The kernel's reach (cells).
    pub reach: i64,
}

/// A Gaussian kernel sampled on the cell lattice: integer offsets and weights.
struct Kernel {
    offsets: Vec<[i64; 3]>,
    weights: Vec<f64>,
}

impl Kernel {
    /// The kernel of displacement covariance `covariance` (m²) on cells of
    /// edge `resolution`; `None` when 3σ is under half a cell (no effect).
    /// No offset exceeds `max_offset` cells on any axis.
    fn new(covariance: &Matrix3, resolution: f64, max_offset: i64) -> Option<Kernel> {
        let sigma = max_sigma(covariance);
        if sigma.is_nan() || 3.0 * sigma < 0.5 * resolution || max_offset < 1 {
            return None;
        }
        let half_cells = ((3.0 * sigma / resolution).ceil() as i64).min(max_offset);
        let stride = (half_cells + MAX_HALF - 1) / MAX_HALF;
        let half = (half_cells + stride - 1) / stride;
        // A sub-cell jitter keeps a degenerate Σ (one direction exact) invertible.
        let jitter = Matrix3::identity() * (1e-3 * resolution).powi(2);
        let information = (covariance + jitter).try_inverse()?;
        let mut offsets = Vec::new();
        let mut weights = Vec::new();
        for i in -half..=half {
            for j in -half..=half {
                for k in -half..=half {
                    let o = [i * stride, j * stride, k * stride];
                    if o.iter().any(|v| v.abs() > max_offset) {
                        continue;
                    }
                    let d = Vector3::new(o[0] as f64, o[1] as f64, o[2] as f64) * resolution;
                    let w = (-0.5 * d.dot(&(information * d))).exp();
                    if w > 1e-4 {
                        offsets.push(o);
                        weights.push(w);
                    }
                }
            }
        }
        Some(Kernel { offsets, weights })
    }
}

/// The largest standard deviation of a covariance (m).
fn max_sigma(covariance: &Matrix3) -> f64 {
    let s = covariance.symmetric_eigenvalues();
    s.max().max(0.0).sqrt()
}

/// Replaces every known cell near a non-free cell of `tree` by its
/// expectation over the shared displacement, `covariance_at(x)` giving
/// `Σ(x)` at a map point. Cells at the free floor far from anything else
/// keep their value (the average of equal values). Errors, before any large
/// allocation, when a slab of the region would not fit in memory.
pub fn expect_over_shared_motion(
    tree: &mut Octree,
    covariance_at: &(dyn Fn(&Point3) -> Matrix3 + Sync),
    clamp: Clamp,
) -> Result<SharedMotionStats, String> {
    let leaves = tree.leaves();
    let Some(region) = Region::around(tree, &leaves, covariance_at, clamp)? else {
        return Ok(SharedMotionStats::default());
    };
    let live = region.live_blocks(&leaves);
    let mut stats = SharedMotionStats {
        reach: region.reach,
        ..Default::default()
    };
    let mut updates: Vec<(Key, f32)> = Vec::new();
    // The leaves that reach the source box (the rest are never read).
    let sources: Vec<&Leaf> = leaves
        .iter()
        .filter(|l| region.reaches_sources(l))
        .collect();
    // One slab of blocks at a time, held densely with its halo, in one buffer.
    let mut buffer = vec![f32::NAN; region.layer() * region.slab_depth() as usize];
    for bz in 0..region.blocks[2] {
        let slab = Slab::fill(&region, bz, &sources, &mut buffer);
        let blocks: Vec<[i64; 3]> = (0..region.blocks[1])
            .flat_map(|by| (0..region.blocks[0]).map(move |bx| [bx, by, bz]))
            .filter(|&b| live[region.block_index(b)])
            .collect();
        let results: Vec<(usize, Vec<(Key, f32)>)> = blocks
            .par_iter()
            .map(|&b| slab.expect_block(&region, b, covariance_at, clamp))
            .collect();
        for (evaluated, out) in results {
            stats.evaluated += evaluated;
            updates.extend(out);
        }
    }
    stats.changed = updates.len();
    for (key, new) in updates {
        let old = tree.query(&key, DEPTH).unwrap_or(0.0);
        tree.update(&key, new - old, clamp);
    }
    Ok(stats)
}

/// Whether `leaf` holds more than the free floor: what the step spreads.
fn above_floor(leaf: &Leaf, floor: f32) -> bool {
    leaf.value > floor + 1e-4
}

/// Cells a leaf of `depth` spans per axis.
fn span(depth: u8) -> i64 {
    1i64 << (DEPTH - depth)
}

/// Where the step works (finest keys, inclusive boxes): the targets, within
/// `reach` of a cell above the free floor, and the sources, within `reach`
/// of a target; cut into blocks of [`BLOCK`]³ targets.
struct Region {
    resolution: f64,
    /// An empty tree of the same resolution: the cells' centres.
    geometry: Octree,
    /// The value of free cells far from anything (the clamp's minimum).
    floor: f32,
    /// The largest σ of the shared displacement over the region (m).
    widest: f64,
    /// The widest kernel's reach (cells).
    reach: i64,
    target_lo: [i64; 3],
    target_hi: [i64; 3],
    source_lo: [i64; 3],
    source_hi: [i64; 3],
    /// Cells of the source box per axis.
    n: [i64; 3],
    /// Blocks of targets per axis.
    blocks: [i64; 3],
}

impl Region {
    /// The region around the cells of `tree` above the free floor, sized by
    /// the widest σ over their box; `None` when nothing is above the floor
    /// or the displacement is under half a cell. Errors when a slab would
    /// not fit in memory.
    fn around(
        tree: &Octree,
        leaves: &[Leaf],
        covariance_at: &(dyn Fn(&Point3) -> Matrix3 + Sync),
        clamp: Clamp,
    ) -> Result<Option<Self>, String> {
        let resolution = tree.resolution();
        let floor = if clamp.min.is_finite() {
            clamp.min
        } else {
            leaves.iter().map(|l| l.value).fold(f32::INFINITY, f32::min)
        };
        // Box of the cells that are not at the free floor.
        let mut lo = [i64::MAX; 3];
        let mut hi = [i64::MIN; 3];
        for leaf in leaves.iter().filter(|l| above_floor(l, floor)) {
            for a in 0..3 {
                lo[a] = lo[a].min(leaf.key.0[a] as i64);
                hi[a] = hi[a].max(leaf.key.0[a] as i64 + span(leaf.depth) - 1);
            }
        }
        if lo[0] > hi[0] {
            return Ok(None);
        }
        let point_of = |k: [i64; 3]| cell_centre(tree, k);
        // The widest σ over the box bounds the reach.
        let corners = (0..8)
            .map(|c| point_of([0, 1, 2].map(|a| if (c >> a) & 1 == 1 { hi[a] } else { lo[a] })));
        let centre = point_of([0, 1, 2].map(|a| (lo[a] + hi[a]) / 2));
        let widest = corners
            .chain(std::iter::once(centre))
            .map(|p| max_sigma(&covariance_at(&p)))
            .fold(0.0, f64::max);
        let reach_cap = 64;
        let identity = Matrix3::identity() * widest * widest;
        let Some(widest_kernel) = Kernel::new(&identity, resolution, reach_cap) else {
            return Ok(None);
        };
        let reach = widest_kernel
            .offsets
            .iter()
            .flat_map(|o| o.map(i64::abs))
            .max()
            .unwrap_or(0);
        let target_lo = lo.map(|v| (v - reach).max(0));
        let target_hi = hi.map(|v| (v + reach).min(65535));
        let source_lo = target_lo.map(|v| (v - reach).max(0));
        let source_hi = target_hi.map(|v| (v + reach).min(65535));
        let region = Self {
            resolution,
            geometry: Octree::new(resolution),
            floor,
            widest,
            reach,
            target_lo,
            target_hi,
            source_lo,
            source_hi,
            n: [0, 1, 2].map(|a| source_hi[a] - source_lo[a] + 1),
            blocks: [0, 1, 2].map(|a| (target_hi[a] - target_lo[a]) / BLOCK + 1),
        };
        let (n, slab_depth) = (region.n, region.slab_depth());
        if n[0] * n[1] * slab_depth > MAX_SLAB_CELLS {
            return Err(format!(
                "the shared-motion step would hold {} x {} x {slab_depth} cells at once (limit \
                 {MAX_SLAB_CELLS}); use a coarser resolution",
                n[0], n[1]
            ));
        }
        Ok(Some(region))
    }

    /// Layers of a slab: a block's and the halo on both sides.
    fn slab_depth(&self) -> i64 {
        BLOCK + 2 * self.reach
    }

    /// Cells of one layer of the source box.
    fn layer(&self) -> usize {
        (self.n[0] * self.n[1]) as usize
    }

    fn block_index(&self, b: [i64; 3]) -> usize {
        ((b[2] * self.blocks[1] + b[1]) * self.blocks[0] + b[0]) as usize
    }

    /// Whether `leaf` overlaps the source box.
    fn reaches_sources(&self, leaf: &Leaf) -> bool {
        (0..3).all(|a| {
            let k = leaf.key.0[a] as i64;
            k <= self.source_hi[a] && k + span(leaf.depth) > self.source_lo[a]
        })
    }

    /// The blocks (of targets) that hold a cell above the free floor,
    /// dilated by the reach: only those can change.
    fn live_blocks(&self, leaves: &[Leaf]) -> Vec<bool> {
        let blocks = self.blocks;
        let mut live = vec![false; (blocks[0] * blocks[1] * blocks[2]) as usize];
        let reach_blocks = (self.reach + BLOCK - 1) / BLOCK;
        for leaf in leaves.iter().filter(|l| above_floor(l, self.floor)) {
            let k0 = leaf.key.0.map(|v| v as i64);
            let b_lo =
                [0, 1, 2].map(|a| ((k0[a] - self.target_lo[a]) / BLOCK - reach_blocks).max(0));
            let b_hi = [0, 1, 2].map(|a| {
                ((k0[a] + span(leaf.depth) - 1 - self.target_lo[a]) / BLOCK + reach_blocks)
                    .min(blocks[a] - 1)
            });
            for z in b_lo[2]..=b_hi[2] {
                for y in b_lo[1]..=b_hi[1] {
                    for x in b_lo[0]..=b_hi[0] {
                        live[self.block_index([x, y, z])] = true;
                    }
                }
            }
        }
        live
    }
}

/// The centre of the finest cell of key `k` (clamped to the key range).
fn cell_centre(tree: &Octree, k: [i64; 3]) -> Point3 {
    tree.center(&Key(k.map(|v| v.clamp(0, 65535) as u16)), DEPTH)
}

/// One slab of the source box, dense: the probabilities of the known cells
/// of the layers `s0..=s1` (NaN: unknown), for the blocks of targets of
/// layers `z0..=z1`.
struct Slab<'a> {
    dense: &'a [f32],
    layer: usize,
    z0: i64,
    z1: i64,
    s0: i64,
    s1: i64,
    source_lo: [i64; 3],
    source_hi: [i64; 3],
    n0: i64,
}

impl<'a> Slab<'a> {
    /// The slab of block layer `bz`, filled from `sources` into `buffer`.
    fn fill(region: &Region, bz: i64, sources: &[&Leaf], buffer: &'a mut [f32]) -> Self {
        let (source_lo, source_hi, n) = (region.source_lo, region.source_hi, region.n);
        let layer = region.layer();
        let z0 = region.target_lo[2] + bz * BLOCK;
        let z1 = (z0 + BLOCK - 1).min(region.target_hi[2]);
        let (s0, s1) = (
            (z0 - region.reach).max(source_lo[2]),
            (z1 + region.reach).min(source_hi[2]),
        );
        let dense = &mut buffer[..layer * (s1 - s0 + 1) as usize];
        dense.fill(f32::NAN);
        for leaf in sources {
            let k0 = leaf.key.0.map(|v| v as i64);
            let k1 = k0.map(|v| v + span(leaf.depth) - 1);
            let (x0, x1) = (k0[0].max(source_lo[0]), k1[0].min(source_hi[0]));
            let (y0, y1) = (k0[1].max(source_lo[1]), k1[1].min(source_hi[1]));
            let (zz0, zz1) = (k0[2].max(s0), k1[2].min(s1));
            if x0 > x1 || y0 > y1 || zz0 > zz1 {
                continue;
            }
            let p = probability(leaf.value as f64) as f32;
            for z in zz0..=zz1 {
                for y in y0..=y1 {
                    let start = (z - s0) as usize * layer
                        + ((y - source_lo[1]) * n[0] + x0 - source_lo[0]) as usize;
                    dense[start..=start + (x1 - x0) as usize].fill(p);
                }
            }
        }
        Self {
            dense,
            layer,
            z0,
            z1,
            s0,
            s1,
            source_lo,
            source_hi,
            n0: n[0],
        }
    }

    /// The probability of cell `k` (NaN: unknown or outside the slab).
    fn at(&self, k: [i64; 3]) -> f32 {
        if k[2] < self.s0
            || k[2] > self.s1
            || (0..2).any(|a| k[a] < self.source_lo[a] || k[a] > self.source_hi[a])
        {
            return f32::NAN;
        }
        self.dense[(k[2] - self.s0) as usize * self.layer
            + ((k[1] - self.source_lo[1]) * self.n0 + k[0] - self.source_lo[0]) as usize]
    }

    /// The expectation of every known cell of block `b` over the
    /// displacement at the block's centre (its σ capped at the region's
    /// widest, for which the halo was sized): the cells evaluated and the
    /// changed ones with their new log-odds.
    fn expect_block(
        &self,
        region: &Region,
        b: [i64; 3],
        covariance_at: &(dyn Fn(&Point3) -> Matrix3 + Sync),
        clamp: Clamp,
    ) -> (usize, Vec<(Key, f32)>) {
        let (target_lo, target_hi) = (region.target_lo, region.target_hi);
        let lo_b = [
            target_lo[0] + b[0] * BLOCK,
            target_lo[1] + b[1] * BLOCK,
            self.z0,
        ];
        let hi_b = [
            (lo_b[0] + BLOCK - 1).min(target_hi[0]),
            (lo_b[1] + BLOCK - 1).min(target_hi[1]),
            self.z1,
        ];
        let mut out = Vec::new();
        let centre = [0, 1, 2].map(|a| (lo_b[a] + hi_b[a]) / 2);
        let mut covariance = covariance_at(&cell_centre(&region.geometry, centre));
        let s = max_sigma(&covariance);
        if s > region.widest {
            covariance *= (region.widest / s).powi(2);
        }
        let Some(kernel) = Kernel::new(&covariance, region.resolution, region.reach) else {
            return (0, out);
        };
        let mut evaluated = 0;
        for z in lo_b[2]..=hi_b[2] {
            for y in lo_b[1]..=hi_b[1] {
                for x in lo_b[0]..=hi_b[0] {
                    let old = self.at([x, y, z]);
                    if old.is_nan() {
                        continue;
                    }
                    evaluated += 1;
                    let (mut sum, mut weight) = (0.0f64, 0.0f64);
                    for (o, w) in kernel.offsets.iter().zip(&kernel.weights) {
                        let p = self.at([x - o[0], y - o[1], z - o[2]]);
                        if !p.is_nan() {
                            sum += w * p as f64;
                            weight += w;
                        }
                    }
                    let new = clamp.apply(logit(sum / weight) as f32);
                    let old = clamp.apply(logit(old as f64) as f32);
                    if (new - old).abs() > 1e-4 {
                        out.push((Key([x, y, z].map(|v| v as u16)), new));
                    }
                }
            }
        }
        (evaluated, out)
    }
}

#[cfg(test)]
mod tests;
