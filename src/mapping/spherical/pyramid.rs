//! The min/max pyramid over a local grid's angular bins (docs/math.md §5.1):
//! level k aggregates 2^k × 2^k bins, so that the merge asks any box of bins
//! for its beams' range extent in at most four reads.

use super::{bin_index, per_bin_into, LocalGrid};
use crate::geometry::{larger, smaller};

/// Aggregate of the beams of a box of angular bins.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxSummary {
    /// Smallest range where some beam's surface band starts (before it every
    /// beam says "free"); `+∞` when no beam.
    pub near: f64,
    /// Smallest range where the surface band of some beam with a return
    /// starts (samples and pulled surfaces left out); `+∞` when none. A cell
    /// between rays finds a surface only through such a beam
    /// (`merge::cell::surface_off_bands`).
    pub hit_near: f64,
    /// Largest range where some beam still carries information (`r + TAIL σ`,
    /// or the maximum range for a no-return beam); `−∞` when no beam.
    pub far: f64,
    /// Largest `TAIL σ_o`: beyond it the origin step is complete.
    pub origin: f64,
    /// Angular bins holding at least one beam.
    pub filled: u32,
    /// Angular bins the (superset) box covers.
    pub bins: u32,
}

impl BoxSummary {
    /// The summary of no bins.
    pub(super) const EMPTY: BoxSummary = BoxSummary {
        near: f64::INFINITY,
        hit_near: f64::INFINITY,
        far: f64::NEG_INFINITY,
        origin: 0.0,
        filled: 0,
        bins: 0,
    };

    /// Widens this summary by `other`'s bins.
    #[inline]
    pub(super) fn add(&mut self, other: &BoxSummary) {
        self.near = smaller(self.near, other.near);
        self.hit_near = smaller(self.hit_near, other.hit_near);
        self.far = larger(self.far, other.far);
        self.origin = larger(self.origin, other.origin);
        self.filled += other.filled;
        self.bins += other.bins;
    }
}

/// The first pyramid level where `span` bins fall in at most two tiles per
/// axis: the least `l` with `span >> l ≤ 2`, i.e. `span < 3 · 2^l`, i.e.
/// `⌊span / 3⌋ < 2^l`, the bit length of `⌊span / 3⌋`.
#[inline]
pub(super) fn query_level(span: usize) -> usize {
    (usize::BITS - (span / 3).leading_zeros()) as usize
}

/// One level of the pyramid over the angular bins.
#[derive(Clone, Debug)]
pub(super) struct Level {
    /// Tiles along azimuth and elevation.
    pub(super) dims: [usize; 2],
    /// Tile `(ta, te)` at `bin_index(dims[0], ta, te)`, as the grid lays its
    /// bins.
    pub(super) cells: Vec<BoxSummary>,
}

impl LocalGrid {
    /// The pyramid over `level0` (the bins' own summaries), its
    /// coarser levels' cells in the memory of `reuse`.
    pub(super) fn build_pyramid(
        &mut self,
        cells: Vec<BoxSummary>,
        mut reuse: impl Iterator<Item = Vec<BoxSummary>>,
    ) {
        let mut dims = [self.azimuth.count, self.elevation.count];
        self.levels = vec![Level { dims, cells }];
        while dims.iter().any(|&d| d > 1) {
            dims = dims.map(|d| d.div_ceil(2));
            self.levels.push(Level {
                dims,
                cells: reuse.next().unwrap_or_default(),
            });
        }
        self.aggregate_levels();
    }

    /// Levels 1 and up from level 0: each tile aggregates its (up to) 2 × 2
    /// cells of the level below.
    pub(super) fn aggregate_levels(&mut self) {
        for level in 1..self.levels.len() {
            let (below, above) = self.levels.split_at_mut(level);
            let (prev, next) = (&below[level - 1], &mut above[0]);
            let dims = prev.dims;
            per_bin_into(&mut next.cells, (next.dims[0], next.dims[1]), |ta, te| {
                let mut s = BoxSummary::EMPTY;
                for a in 2 * ta..(2 * ta + 2).min(dims[0]) {
                    for e in 2 * te..(2 * te + 2).min(dims[1]) {
                        s.add(&prev.cells[bin_index(dims[0], a, e)]);
                    }
                }
                s
            });
        }
    }

    /// The pyramid level of tiles of `2^level` × `2^level` bins, or the
    /// coarsest there is.
    pub fn tile_level(&self, level: usize) -> usize {
        level.min(self.levels.len().saturating_sub(1))
    }

    /// The aggregate over the tile `(ta, te)` of [`LocalGrid::tile_level`]
    /// `level`: bins `ta·2^level ..` by `te·2^level ..`.
    #[inline]
    pub fn tile_summary(&self, level: usize, ta: usize, te: usize) -> &BoxSummary {
        let l = &self.levels[level];
        &l.cells[bin_index(l.dims[0], ta, te)]
    }

    /// The aggregate over a superset of the bins `[a0..=a1] x [e0..=e1]`: the
    /// coarsest pyramid level where the box spans at most two cells per axis.
    pub fn query(&self, a: (usize, usize), e: (usize, usize)) -> BoxSummary {
        let span = (a.1 - a.0).max(e.1 - e.0) + 1;
        let level = query_level(span).min(self.levels.len() - 1);
        let l = &self.levels[level];
        let mut out = BoxSummary::EMPTY;
        for aa in a.0 >> level..=a.1 >> level {
            for ee in e.0 >> level..=e.1 >> level {
                out.add(&l.cells[bin_index(l.dims[0], aa, ee)]);
            }
        }
        out
    }

    /// The largest range at which any beam carries information.
    pub fn reach(&self) -> f64 {
        self.levels.last().map_or(f64::NEG_INFINITY, |l| {
            l.cells
                .iter()
                .map(|c| c.far)
                .fold(f64::NEG_INFINITY, f64::max)
        })
    }
}
