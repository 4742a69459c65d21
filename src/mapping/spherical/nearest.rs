//! Each bin's nearest surface (docs/math.md §5.4) and the pyramid's level 0,
//! in two passes over the bins: the first reads every bin's beams once for
//! both, the second pulls each bin's range towards its 3 × 3 neighbours.
//! Both passes write each output once, into memory reused from the last
//! grid (no fill beforehand).

use super::pyramid::BoxSummary;
use super::{bin_at_index, bin_index, LocalGrid};
use crate::geometry::{larger, smaller};
use crate::mapping::chord::{Surface, TAIL};
use rayon::prelude::*;

/// The entry of an empty bin among its neighbours' own surfaces: `+∞`, like
/// a no-return bin's, so it never lowers a neighbour's range.
const NOTHING: Surface = Surface {
    range: f64::INFINITY,
    sigma: 0.0,
    sigma_origin: 0.0,
};

impl LocalGrid {
    /// The bins' nearest surfaces into `self.surfaces` and the pyramid's
    /// level 0 into `level0` (`na · ne` cells, in [`bin_index`] order), with `own` (each
    /// bin's own nearest beam) as working memory.
    ///
    /// The surface of a bin is the closest of its own beams, pulled to
    /// half-way towards any nearer neighbour (the surface between two beams
    /// taken as linear in angle), or to a returning neighbour's range when
    /// the bin's own beams all had no return (a silhouette against nothing);
    /// its σ grows to the widest of each neighbour that lowers the range, the
    /// neighbours taken azimuth by azimuth. `None`: an empty bin.
    pub(super) fn build_surfaces_and_level0(
        &mut self,
        own: &mut Vec<Surface>,
        level0: &mut Vec<BoxSummary>,
    ) {
        let (na, ne) = (self.azimuth.count, self.elevation.count);
        let max_range = self.max_range;
        // Pass 1: each bin's beams, for its own surface and its summary (the
        // summary's `near` without the bin's surface yet).
        (0..na * ne)
            .into_par_iter()
            .map(|i| {
                let beams = &self.beams[self.offsets[i] as usize..self.offsets[i + 1] as usize];
                let mut s = BoxSummary::EMPTY;
                for b in beams {
                    s.near = smaller(s.near, b.band_start(max_range));
                    if b.range.is_finite() {
                        s.hit_near = smaller(s.hit_near, b.band_start(max_range));
                    }
                    s.far = larger(s.far, b.reach(max_range));
                    s.origin = larger(s.origin, TAIL * b.sigma_origin);
                }
                s.filled = u32::from(!beams.is_empty());
                s.bins = 1;
                let nearest = beams
                    .iter()
                    .map(super::super::chord::Beam::surface)
                    .reduce(|best, b| Surface {
                        range: if b.range < best.range {
                            b.range
                        } else {
                            best.range
                        },
                        sigma: larger(best.sigma, b.sigma),
                        sigma_origin: larger(best.sigma_origin, b.sigma_origin),
                    })
                    .unwrap_or(NOTHING);
                (s, nearest)
            })
            .unzip_into_vecs(level0, own);
        // Pass 2: the neighbourhoods, and each summary's `near` lowered to
        // its bin's surface band.
        let own = &own[..];
        let mut surfaces = std::mem::take(&mut self.surfaces);
        level0
            .par_iter_mut()
            .enumerate()
            .map(|(i, cell)| {
                if self.offsets[i] == self.offsets[i + 1] {
                    return None;
                }
                let (a, e) = bin_at_index(na, i);
                let surface = pulled(own, (na, ne), a, e);
                cell.near = smaller(cell.near, surface.band_start(max_range));
                Some(surface)
            })
            .collect_into_vec(&mut surfaces);
        self.surfaces = surfaces;
    }
}

/// Bin `(a, e)`'s own surface pulled by its 3 × 3 neighbourhood, azimuth
/// by azimuth and within each by elevation (clipped at the grid's border;
/// the bin itself never lowers it).
#[inline]
fn pulled(own: &[Surface], (na, ne): (usize, usize), a: usize, e: usize) -> Surface {
    let mut surface = own[bin_index(na, a, e)];
    let base = surface.range;
    let finite = base.is_finite();
    // Selects, not a branch: whether a neighbour is nearer is a coin toss
    // on a smooth surface.
    let mut lower = |other: &Surface| {
        let bound = if finite {
            0.5 * (base + other.range)
        } else {
            other.range
        };
        let nearer = bound < surface.range;
        let sigma = larger(surface.sigma, other.sigma);
        surface.range = if nearer { bound } else { surface.range };
        surface.sigma = if nearer { sigma } else { surface.sigma };
    };
    if a > 0 && a + 1 < na && e > 0 && e + 1 < ne {
        // Inside: three rows (of elevation) of three bins known to the
        // compiler.
        let rows: [&[Surface; 3]; 3] = std::array::from_fn(|dy| {
            let start = bin_index(na, a - 1, e + dy - 1);
            own[start..start + 3].try_into().expect("three bins")
        });
        for dx in 0..3 {
            for row in rows {
                lower(&row[dx]);
            }
        }
    } else {
        for x in a.saturating_sub(1)..(a + 2).min(na) {
            for y in e.saturating_sub(1)..(e + 2).min(ne) {
                lower(&own[bin_index(na, x, y)]);
            }
        }
    }
    surface
}
