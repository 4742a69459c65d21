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

use super::octree::{Clamp, Key, Octree, DEPTH};
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
    let resolution = tree.resolution();
    let leaves = tree.leaves();
    let floor = if clamp.min.is_finite() {
        clamp.min
    } else {
        leaves.iter().map(|l| l.value).fold(f32::INFINITY, f32::min)
    };
    let interesting = |v: f32| v > floor + 1e-4;
    let span = |depth: u8| 1i64 << (DEPTH - depth);
    // Box of the cells that are not at the free floor (finest keys, inclusive).
    let mut lo = [i64::MAX; 3];
    let mut hi = [i64::MIN; 3];
    for leaf in leaves.iter().filter(|l| interesting(l.value)) {
        for a in 0..3 {
            lo[a] = lo[a].min(leaf.key.0[a] as i64);
            hi[a] = hi[a].max(leaf.key.0[a] as i64 + span(leaf.depth) - 1);
        }
    }
    if lo[0] > hi[0] {
        return Ok(SharedMotionStats::default());
    }
    let point_of = |k: [i64; 3]| tree.center(&Key(k.map(|v| v.clamp(0, 65535) as u16)), DEPTH);
    // The widest σ over the box bounds the reach.
    let corners =
        (0..8).map(|c| point_of([0, 1, 2].map(|a| if (c >> a) & 1 == 1 { hi[a] } else { lo[a] })));
    let centre = point_of([0, 1, 2].map(|a| (lo[a] + hi[a]) / 2));
    let widest = corners
        .chain(std::iter::once(centre))
        .map(|p| max_sigma(&covariance_at(&p)))
        .fold(0.0, f64::max);
    let reach_cap = 64;
    let Some(widest_kernel) = Kernel::new(
        &(Matrix3::identity() * widest * widest),
        resolution,
        reach_cap,
    ) else {
        return Ok(SharedMotionStats::default());
    };
    let reach = widest_kernel
        .offsets
        .iter()
        .flat_map(|o| o.map(i64::abs))
        .max()
        .unwrap_or(0);
    // Targets: within `reach` of a non-free cell. Sources: within `reach` of a target.
    let target_lo = lo.map(|v| (v - reach).max(0));
    let target_hi = hi.map(|v| (v + reach).min(65535));
    let source_lo = target_lo.map(|v| (v - reach).max(0));
    let source_hi = target_hi.map(|v| (v + reach).min(65535));
    let n = [0, 1, 2].map(|a| source_hi[a] - source_lo[a] + 1);
    let slab_depth = BLOCK + 2 * reach;
    if n[0] * n[1] * slab_depth > MAX_SLAB_CELLS {
        return Err(format!(
            "the shared-motion step would hold {} x {} x {slab_depth} cells at once (limit \
             {MAX_SLAB_CELLS}); use a coarser resolution",
            n[0], n[1]
        ));
    }
    // Blocks (of targets) that hold a non-free cell, dilated by the reach:
    // only those can change.
    let blocks = [0, 1, 2].map(|a| (target_hi[a] - target_lo[a]) / BLOCK + 1);
    let block_index = |b: [i64; 3]| ((b[2] * blocks[1] + b[1]) * blocks[0] + b[0]) as usize;
    let mut live = vec![false; (blocks[0] * blocks[1] * blocks[2]) as usize];
    let reach_blocks = (reach + BLOCK - 1) / BLOCK;
    for leaf in leaves.iter().filter(|l| interesting(l.value)) {
        let k0 = leaf.key.0.map(|v| v as i64);
        let b_lo = [0, 1, 2].map(|a| ((k0[a] - target_lo[a]) / BLOCK - reach_blocks).max(0));
        let b_hi = [0, 1, 2].map(|a| {
            ((k0[a] + span(leaf.depth) - 1 - target_lo[a]) / BLOCK + reach_blocks)
                .min(blocks[a] - 1)
        });
        for z in b_lo[2]..=b_hi[2] {
            for y in b_lo[1]..=b_hi[1] {
                for x in b_lo[0]..=b_hi[0] {
                    live[block_index([x, y, z])] = true;
                }
            }
        }
    }
    let mut stats = SharedMotionStats {
        reach,
        ..Default::default()
    };
    let mut updates: Vec<(Key, f32)> = Vec::new();
    // The leaves that reach the source box (the rest are never read).
    let sources: Vec<_> = leaves
        .iter()
        .filter(|l| {
            (0..3).all(|a| {
                let k = l.key.0[a] as i64;
                k <= source_hi[a] && k + span(l.depth) > source_lo[a]
            })
        })
        .collect();
    // One slab of blocks at a time, held densely with its halo, in one buffer.
    let layer = (n[0] * n[1]) as usize;
    let mut buffer = vec![f32::NAN; layer * slab_depth as usize];
    for bz in 0..blocks[2] {
        let z0 = target_lo[2] + bz * BLOCK;
        let z1 = (z0 + BLOCK - 1).min(target_hi[2]);
        let (s0, s1) = (
            (z0 - reach).max(source_lo[2]),
            (z1 + reach).min(source_hi[2]),
        );
        let dense = &mut buffer[..layer * (s1 - s0 + 1) as usize];
        dense.fill(f32::NAN);
        for leaf in &sources {
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
        let at = |k: [i64; 3]| -> f32 {
            if k[2] < s0 || k[2] > s1 || (0..2).any(|a| k[a] < source_lo[a] || k[a] > source_hi[a])
            {
                return f32::NAN;
            }
            dense[(k[2] - s0) as usize * layer
                + ((k[1] - source_lo[1]) * n[0] + k[0] - source_lo[0]) as usize]
        };
        let slab: Vec<[i64; 2]> = (0..blocks[1])
            .flat_map(|by| (0..blocks[0]).map(move |bx| [bx, by]))
            .filter(|b| live[block_index([b[0], b[1], bz])])
            .collect();
        let results: Vec<(usize, Vec<(Key, f32)>)> = slab
            .par_iter()
            .map(|b| {
                let lo_b = [target_lo[0] + b[0] * BLOCK, target_lo[1] + b[1] * BLOCK, z0];
                let hi_b = [
                    (lo_b[0] + BLOCK - 1).min(target_hi[0]),
                    (lo_b[1] + BLOCK - 1).min(target_hi[1]),
                    z1,
                ];
                let centre = point_of([0, 1, 2].map(|a| (lo_b[a] + hi_b[a]) / 2));
                let mut covariance = covariance_at(&centre);
                // The halo was sized for the widest σ: cap this block's to it.
                let s = max_sigma(&covariance);
                if s > widest {
                    covariance *= (widest / s).powi(2);
                }
                let mut evaluated = 0;
                let mut out = Vec::new();
                let Some(kernel) = Kernel::new(&covariance, resolution, reach) else {
                    return (0, out);
                };
                for z in lo_b[2]..=hi_b[2] {
                    for y in lo_b[1]..=hi_b[1] {
                        for x in lo_b[0]..=hi_b[0] {
                            let old = at([x, y, z]);
                            if old.is_nan() {
                                continue;
                            }
                            evaluated += 1;
                            let (mut sum, mut weight) = (0.0f64, 0.0f64);
                            for (o, w) in kernel.offsets.iter().zip(&kernel.weights) {
                                let p = at([x - o[0], y - o[1], z - o[2]]);
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
            })
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

#[cfg(test)]
mod tests;
