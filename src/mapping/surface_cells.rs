//! The finest cells each beam's surface band reaches, with the most confident
//! chord probability there: `H` of docs/math.md §5.4 looked up, not searched.
//!
//! A beam says a surface may lie inside cell C only where its chord `[a, b]`
//! through C meets its surface band `[r − TAIL σ, r + TAIL σ]`: elsewhere
//! `P(a ≤ λ ≤ b)` is exactly 0 ([`CellModel::split`]). So `H(C)`, the maximum
//! over the beams crossing C of that probability, is the maximum over the
//! beams whose band *segment* touches C. This index walks each beam's band
//! once (a few cells at most, whatever the cell's angular extent) instead of
//! every cell visiting every beam of its solid angle.
//!
//! \[DESIGN\] Cells are found by cutting the band into pieces no longer than a
//! cell edge and listing the cells of each piece's bounding box (at most two
//! per axis), widened by a millionth of a cell; the exact ray/box chord then
//! decides. The chord is computed as the merge computes it (same origin,
//! inverse direction, centre and half edge), so the value is the merge's to
//! the bit.

use super::chord::{origin_step, ray_box, Beam, CellModel};
use super::octree::{Key, Octree, DEPTH};
use super::spherical::LocalGrid;
use crate::geometry::{floor, larger, smaller, Vector3};
use blocks::{Blocks, Cursor};
use rayon::prelude::*;

/// The chance that a surface lies inside the chord `[a, b]` of `beam`, times
/// the origin step at the chord's middle: one beam's term of `H` (§5.4).
#[inline]
pub fn chord_surface(model: &CellModel, beam: &Beam, a: f64, b: f64, max_range: f64) -> f64 {
    model.split(beam, a, b, max_range).1 * origin_step(0.5 * (a + b), beam.sigma_origin)
}

/// `min(H, p_hi)` of every finest cell some beam's surface band touches with
/// a positive chord probability (absent: 0 from every beam that crosses it;
/// at `p_hi` the merge's verdict is `p_hi` whatever else is found).
#[derive(Clone, Debug, Default)]
pub struct SurfaceCells {
    cells: Blocks,
}

/// The cells of an aligned block of the index ([`SurfaceCells::block`]).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceBlock<'a>(Option<&'a [Held; blocks::CELLS]>);

/// Finest cells a side of a [`SurfaceBlock`], as a shift.
pub const BLOCK_BITS: u32 = blocks::SIDE_BITS;

impl SurfaceBlock<'_> {
    /// No cells.
    pub const NONE: SurfaceBlock<'static> = SurfaceBlock(None);

    /// [`SurfaceCells::get`] of the finest cell `key` of this block.
    #[inline]
    pub fn get(&self, key: &Key) -> Option<f64> {
        let cells = self.0?;
        let held = cells[blocks::split(key).1];
        (held.value > 0.0).then_some(held.value)
    }
}

/// A cell's `min(H, p_hi)` so far, and how far outside a chord a beam's
/// surface must lie (in its σ) for that beam to be unable to raise it.
///
/// A chord `[a, b]` that the surface `λ ~ N(r, σ²)` misses by
/// `x = max(a − r, r − b)/σ ≥ 0` holds it with `P(a ≤ λ ≤ b) ≤ Φ(−x) ≤
/// φ(x) · 4/(3x + √(x² + 8))` (Sampford's bound on Mills' ratio, within 2%
/// of the tail from x = 1 on; `Φ(−x) ≤ ½` for any x ≥ 0), and the origin
/// step only lowers that. So once that bound is below the value held by more
/// than the rounding of `1 − Φ(x)` (1e-14 here, a hundred times it), the
/// beam's term cannot raise it, computed or exact: it is skipped, and the
/// index is the same to the bit (the most evaluations by far are such tails,
/// 92% of them on the insertion benchmark's scans at 2 cm).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Held {
    value: f64,
    settled_beyond: f64,
}

impl Held {
    fn new(value: f64) -> Self {
        let slack = value - 1e-14;
        let settled_beyond = if slack <= 0.0 {
            f64::INFINITY
        } else if slack >= 0.5 {
            0.0
        } else {
            mills::beyond(slack)
        };
        Self {
            value,
            settled_beyond,
        }
    }

    /// Whether `beam` (with a return and σ > 0) surely cannot raise this
    /// value through the chord `[a, b]`.
    #[inline]
    fn settled_for(&self, beam: &Beam, a: f64, b: f64) -> bool {
        let miss = (a - beam.range).max(beam.range - b) / beam.sigma;
        beam.range.is_finite() && beam.sigma > 0.0 && miss >= self.settled_beyond
    }
}

/// Beams per parallel task.
const CHUNK: usize = 4096;

/// A packed value no key packs to ([`packed`] uses 48 bits).
const NO_CELL: u64 = u64::MAX;

/// Slots of the cache of cells known at `p_hi`.
const FULL_SLOTS: usize = 64;

/// The slot of `cell` in the cache of cells at `p_hi`: the low two bits of
/// each coordinate, so that two cells fewer than four apart along every
/// axis (a band piece's box and its neighbours') never share a slot.
#[inline]
fn full_slot(cell: [i64; 3]) -> usize {
    ((cell[0] & 3) | (cell[1] & 3) << 2 | (cell[2] & 3) << 4) as usize
}

/// A finest key packed into one integer.
#[inline]
fn packed(key: &Key) -> u64 {
    u64::from(key.0[0]) | u64::from(key.0[1]) << 16 | u64::from(key.0[2]) << 32
}

impl SurfaceCells {
    /// The index of `grid`'s beams on the finest cells of `geometry` (its
    /// resolution; the tree's contents are not read).
    /// The grid's surface samples between beams, if any
    /// ([`LocalGrid::add_surface_samples`]), count as beams here.
    pub fn new(grid: &LocalGrid, model: &CellModel, geometry: &Octree) -> Self {
        let (beams, inverse) = grid.beams();
        let (samples, sample_inverse) = grid.samples();
        let cells = beams
            .par_chunks(CHUNK)
            .zip(inverse.par_chunks(CHUNK))
            .chain(
                samples
                    .par_chunks(CHUNK)
                    .zip(sample_inverse.par_chunks(CHUNK)),
            )
            .fold(Blocks::default, |mut cells, (beams, inverse)| {
                let mut full = [NO_CELL; FULL_SLOTS];
                let mut cursor = Cursor::default();
                for (beam, inv) in beams.iter().zip(inverse) {
                    let walk = (&mut cells, &mut cursor, &mut full);
                    band_cells(grid, model, geometry, beam, inv, walk);
                }
                cells
            })
            .reduce(Blocks::default, Blocks::merge);
        Self { cells }
    }

    /// `min(H, p_hi)` of the finest cell `key` if some beam's band gives it
    /// a positive value.
    #[inline]
    pub fn get(&self, key: &Key) -> Option<f64> {
        self.block(key).get(key)
    }

    /// The index's cells in the aligned block of `2^BLOCK_BITS` finest cells
    /// a side holding `key`: one look-up for all of them.
    #[inline]
    pub fn block(&self, key: &Key) -> SurfaceBlock<'_> {
        SurfaceBlock(self.cells.block(key))
    }

    /// Number of cells held.
    pub fn len(&self) -> usize {
        self.cells.raised().count()
    }

    /// Whether no cell is held.
    pub fn is_empty(&self) -> bool {
        self.cells.raised().next().is_none()
    }
}

/// Raises `cells[C]` to `min(h, p_hi)` for each finest cell C whose chord on
/// `beam` meets its surface band with `h > 0`; a cell already at `p_hi` is
/// not evaluated again. `full` remembers cells found at `p_hi`, one per
/// [`full_slot`]; values only rise, so a cell remembered stays at `p_hi`, and
/// the next beams (which mostly reach the same cells) pass it over without a
/// look into `cells`; `cursor` is the block of `cells` used last.
fn band_cells(
    grid: &LocalGrid,
    model: &CellModel,
    geometry: &Octree,
    beam: &Beam,
    inverse: &Vector3,
    (cells, cursor, full): (&mut Blocks, &mut Cursor, &mut [u64; FULL_SLOTS]),
) {
    if !beam.range.is_finite() {
        return;
    }
    let max_range = grid.max_range;
    let (start, end) = (beam.band_start(max_range).max(0.0), beam.reach(max_range));
    if start.is_nan() || end.is_nan() || start > end {
        return;
    }
    let resolution = geometry.resolution();
    let half = geometry.node_size(DEPTH) * 0.5;
    let widen = 1e-6 * resolution;
    // The pieces' boxes are widened by far more than a product's rounding.
    let per_cell = 1.0 / resolution;
    let pieces = ((end - start) / resolution).ceil().clamp(1.0, 1e6) as usize;
    let point = |t: f64| grid.origin + beam.direction * t;
    // Cells listed by the previous piece (neighbouring pieces share some).
    let mut previous = [[0i64; 3]; 2];
    for piece in 0..pieces {
        let (ta, tb) = (
            start + (end - start) * piece as f64 / pieces as f64,
            start + (end - start) * (piece + 1) as f64 / pieces as f64,
        );
        let (pa, pb) = (point(ta), point(tb));
        let range: [[i64; 2]; 3] = std::array::from_fn(|axis| {
            let (lo, hi) = (smaller(pa[axis], pb[axis]), larger(pa[axis], pb[axis]));
            [
                floor((lo - widen) * per_cell),
                floor((hi + widen) * per_cell),
            ]
        });
        // Half-open ranges: the same cells of the tree, fewer instructions
        // than `..=`.
        for x in range[0][0]..range[0][1].saturating_add(1) {
            for y in range[1][0]..range[1][1].saturating_add(1) {
                for z in range[2][0]..range[2][1].saturating_add(1) {
                    let cell = [x, y, z];
                    let seen = piece > 0
                        && (0..3).all(|a| previous[0][a] <= cell[a] && cell[a] <= previous[1][a]);
                    if seen {
                        continue;
                    }
                    let Some(key) = key_of(cell) else {
                        continue;
                    };
                    // Most cells a band reaches are already at p_hi from a
                    // neighbouring beam: look before computing the chord.
                    let packed = packed(&key);
                    let slot = full_slot(cell);
                    if full[slot] == packed {
                        continue;
                    }
                    let held = cells.cell_mut(&key, cursor);
                    if held.value >= model.p_hi {
                        full[slot] = packed;
                        continue;
                    }
                    let centre = geometry.center(&key, DEPTH).coords;
                    let Some((a, b)) = ray_box(&grid.origin, inverse, &centre, half) else {
                        continue;
                    };
                    // Most of the rest only reach it with their band's tail.
                    if held.value > 0.0 && held.settled_for(beam, a, b) {
                        continue;
                    }
                    let h = chord_surface(model, beam, a, b, max_range).min(model.p_hi);
                    if h > held.value {
                        *held = Held::new(h);
                        if h >= model.p_hi {
                            full[slot] = packed;
                        }
                    }
                }
            }
        }
        previous = [range.map(|r| r[0]), range.map(|r| r[1])];
    }
}

/// The key of the finest cell with integer coordinates `cell` (floor of the
/// position over the resolution), if inside the tree's cube.
#[inline]
fn key_of(cell: [i64; 3]) -> Option<Key> {
    let mut key = [0u16; 3];
    for (out, c) in key.iter_mut().zip(cell) {
        *out = u16::try_from(c + super::octree::CENTER).ok()?;
    }
    Some(Key(key))
}

mod blocks;
mod mills;
#[cfg(test)]
mod tests;
