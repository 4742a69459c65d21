//! What one viewpoint's grid says about one finest cell (docs/math.md
//! §5.4): `H`, how surely a surface lies inside it, from the beams whose
//! centre lines cross it; `F`, the share of it seen in front of the surface,
//! from its corners; and their combination. [`cell_occupancy`] is the
//! reference the merge's search is tested against.

use crate::geometry::Vector3;
use crate::mapping::chord::{ray_box, Beam, CellModel};
use crate::mapping::octree::{Key, Octree, DEPTH};
use crate::mapping::spherical::{BinBox, LocalGrid};
use crate::mapping::surface_cells::chord_surface;

/// The corner offsets (0 or 1 per axis) of corner `i`: bit 0 of `i` is x,
/// bit 1 is y, bit 2 is z.
#[inline]
pub(super) fn corner_offset(i: usize) -> [u16; 3] {
    [(i & 1) as u16, (i >> 1 & 1) as u16, (i >> 2 & 1) as u16]
}

/// A finest cell as the cell model sees it: centre, half edge and corners
/// (corner `i` as in `corner_offset`).
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
/// reaches `p_hi`, where `combine` stops looking.
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
/// not in the [`SurfaceCells`](crate::mapping::surface_cells::SurfaceCells)): every beam crossing C gives 0, so `H` is 0
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
