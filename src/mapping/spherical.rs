//! The local spherical grid of one viewpoint (docs/math.md §5.1): azimuth x
//! elevation bins around the mean sensor origin, each holding the beams that
//! fall in it (propagated range, σ along the beam, σ of the origin), with a
//! min/max pyramid over the bins for the merge's box queries.
//!
//! The grid keeps no range bins: a cell's value is computed from each beam's
//! chord through it (§5.4, `mapping::chord`), so nothing is sampled along the
//! beam and no bin width enters the model.
//!
//! \[DESIGN\] The grid's axes follow the nominal sensor, not the scene: grid x is
//! the boresight (camera z), y the camera x, z the camera y. A beam at
//! horizontal angle h and vertical angle v then has azimuth h and elevation v,
//! the raster maps onto the angular bins one to one, and no viewpoint puts its
//! field of view across the poles or the azimuth wrap (§8, open question 3,
//! leaves the choice open). Merging costs one extra rotation.

use super::chord::{Beam, Surface};
use crate::geometry::{floor, Matrix3, Vector3};
use rayon::prelude::*;
use tangent::TangentBins;

/// A bin axis: `count` bins of `step` from `start`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Axis {
    /// Lower edge of bin 0.
    pub start: f64,
    /// Bin width.
    pub step: f64,
    /// Number of bins.
    pub count: usize,
}

impl Axis {
    /// The (unclamped) bin index of `v`.
    #[inline]
    pub fn index(&self, v: f64) -> isize {
        floor((v - self.start) / self.step) as isize
    }

    /// Centre of bin `i`.
    #[inline]
    pub fn centre(&self, i: usize) -> f64 {
        self.start + (i as f64 + 0.5) * self.step
    }

    /// Upper edge of the last bin.
    pub fn end(&self) -> f64 {
        self.start + self.step * self.count as f64
    }
}

/// The angular bins a query covers, and the range interval of the query ball.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinBox {
    /// Azimuth bins, inclusive.
    pub azimuth: (usize, usize),
    /// Elevation bins, inclusive.
    pub elevation: (usize, usize),
    /// Nearest and farthest distance of the ball from the origin.
    pub range: (f64, f64),
    /// Whether the ball reaches outside the grid's field of view.
    pub outside: bool,
    /// The bin holding the ball's centre, if any (as [`LocalGrid::bin_of`]).
    pub centre: Option<(usize, usize)>,
}

/// Where a local grid sits and how its angular bins are laid out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridLayout {
    /// Mean sensor origin û in the scene frame.
    pub origin: Vector3,
    /// Rotation taking grid coordinates to scene coordinates.
    pub scene_from_grid: Matrix3,
    /// Azimuth bins (rad).
    pub azimuth: Axis,
    /// Elevation bins (rad).
    pub elevation: Axis,
    /// The scanner's maximum range (m).
    pub max_range: f64,
}

/// A beam's end as the modeller knows it, in the scene frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BeamEnd {
    /// A measured point with its propagated covariance.
    Hit {
        /// The propagated mean, scene frame.
        point: Vector3,
        /// Its propagated covariance.
        covariance: Matrix3,
    },
    /// No return: free space up to the maximum range.
    Miss {
        /// The beam's unit direction, scene frame.
        direction: Vector3,
    },
}

/// `(r, azimuth, elevation)` of a grid-frame vector.
#[inline]
pub fn spherical(v: &Vector3) -> (f64, f64, f64) {
    let r = v.norm();
    (r, v.y.atan2(v.x), v.z.atan2((v.x * v.x + v.y * v.y).sqrt()))
}

/// The placeholder of a beam left out of the grid (its bin one past the last:
/// never placed).
const LEFT_OUT: Beam = Beam {
    direction: Vector3::new(0.0, 0.0, 0.0),
    range: 0.0,
    sigma: 0.0,
    sigma_origin: 0.0,
};

/// Where bin `(a, e)` lies on a grid (or pyramid level) `na` bins wide in
/// azimuth: row by row in elevation, the raster's order, so that a scan's
/// beams land in bin order nearly as they come.
#[inline]
pub(super) fn bin_index(na: usize, a: usize, e: usize) -> usize {
    e * na + a
}

/// The bin `(a, e)` at [`bin_index`] `i` of a grid `na` bins wide.
#[inline]
fn bin_at_index(na: usize, i: usize) -> (usize, usize) {
    (i % na, i / na)
}

/// `f(a, e)` for every bin of an `na` × `ne` grid into `out`, in
/// [`bin_index`] order, in parallel; `out`'s memory is reused, each bin written once
/// (no fill beforehand: on grids of megabytes the fill costs as much as the
/// bins' own work).
fn per_bin_into<T: Send>(
    out: &mut Vec<T>,
    (na, ne): (usize, usize),
    f: impl Fn(usize, usize) -> T + Sync + Send,
) {
    (0..na * ne)
        .into_par_iter()
        .map(|i| {
            let (a, e) = bin_at_index(na, i);
            f(a, e)
        })
        .collect_into_vec(out);
}

/// The memory of a local grid, its working arrays included, to build the
/// next grid in: a map's viewpoints then touch fresh pages once, not once
/// per viewpoint (page faults cost a few percent of a coarse map).
#[derive(Debug, Default)]
pub struct GridBuffers {
    bin_of: Vec<u32>,
    unbinned: Vec<Beam>,
    next: Vec<u32>,
    sorted: Vec<u32>,
    own: Vec<Surface>,
    offsets: Vec<u32>,
    beams: Vec<Beam>,
    inverse: Vec<Vector3>,
    surfaces: Vec<Option<Surface>>,
    levels: Vec<Vec<BoxSummary>>,
}

/// A copy carries no spare memory: buffers hold no content a grid reads.
impl Clone for GridBuffers {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// A filled local grid.
#[derive(Clone, Debug)]
pub struct LocalGrid {
    /// Mean sensor origin û in the scene frame.
    pub origin: Vector3,
    /// Rotation taking grid coordinates to scene coordinates.
    pub scene_from_grid: Matrix3,
    /// Azimuth bins (rad).
    pub azimuth: Axis,
    /// Elevation bins (rad).
    pub elevation: Axis,
    /// The scanner's maximum range (m): how far a no-return beam clears.
    pub max_range: f64,
    /// [`lookup::ANGLE_SLACK`] in bins of each axis.
    slack: [f64; 2],
    /// The azimuth and elevation bins by the tangent of their angles.
    tangents: [TangentBins; 2],
    /// Beams of bin `i` ([`bin_index`]): `beams[offsets[i]..offsets[i+1]]`.
    offsets: Vec<u32>,
    beams: Vec<Beam>,
    /// Componentwise inverse of each beam's direction (for ray/box chords).
    inverse: Vec<Vector3>,
    /// Per bin, the nearest the surface may come within the bin's solid
    /// angle (see `bin_surface`); `None` for an empty bin.
    surfaces: Vec<Option<Surface>>,
    /// Level k aggregates 2^k bins a side; level 0 is the bins.
    levels: Vec<Level>,
    /// Surface samples between neighbouring beams, with their inverse
    /// directions (empty unless [`LocalGrid::add_surface_samples`]).
    samples: Vec<Beam>,
    sample_inverse: Vec<Vector3>,
    /// The working arrays the grid was built with, kept for the next.
    spare: GridBuffers,
}

/// How a grid bins beams: the grid's frame and axes, the propagated sensor
/// origin, and the nominal directions' bins when they fit.
struct Binning<'a> {
    origin: Vector3,
    origin_covariance: &'a Matrix3,
    grid_from_scene: Matrix3,
    axes: [&'a Axis; 2],
    slack: [f64; 2],
    tangents: &'a [TangentBins; 2],
    nominal: Option<&'a NominalBins<'a>>,
    /// One past the last bin: the bin of a beam left out.
    bins: usize,
}

impl Binning<'_> {
    /// Beam `i`'s bin and its direction, range and σ seen from the origin
    /// (docs/math.md §4.5); a beam that carries nothing, hits the origin or
    /// falls outside the bins is left out.
    fn bin(&self, i: usize, end: Option<BeamEnd>) -> (u32, Beam) {
        let left_out = (self.bins as u32, LEFT_OUT);
        let Some(end) = end else {
            return left_out;
        };
        let (direction, range, sigma) = match end {
            BeamEnd::Hit { point, covariance } => {
                let d = point - self.origin;
                let r = d.norm();
                if r.is_nan() || r <= 0.0 {
                    return left_out;
                }
                let v = d / r;
                let sigma2 = (v.transpose() * covariance * v)[0].max(0.0);
                (v, r, sigma2.sqrt())
            }
            BeamEnd::Miss { direction } => (direction.normalize(), f64::INFINITY, 0.0),
        };
        let sigma_origin = (direction.transpose() * self.origin_covariance * direction)[0]
            .max(0.0)
            .sqrt();
        let in_grid = self.grid_from_scene * direction;
        let bin = match self.nominal.and_then(|n| n.bin_near(i, &in_grid)) {
            Some(bin) => bin,
            None => {
                let Some((a, e)) =
                    lookup::direction_bin(self.axes, self.slack, self.tangents, &in_grid)
                else {
                    return left_out;
                };
                bin_index(self.axes[0].count, a, e) as u32
            }
        };
        let beam = Beam {
            direction,
            range,
            sigma,
            sigma_origin,
        };
        (bin, beam)
    }
}

/// A stable counting sort of beams by bin, in the memory of a grid's
/// buffers: beams keep their input order within a bin; those left out
/// (bin `bins`) are not placed.
struct BinSort<'a> {
    bin_of: &'a [u32],
    bins: usize,
    offsets: &'a mut Vec<u32>,
    next: &'a mut Vec<u32>,
    sorted: &'a mut Vec<u32>,
}

impl BinSort<'_> {
    /// Sorts `unbinned` (input order) into `beams` (bin order), each with
    /// its inverse direction in `inverse`; `offsets[b]..offsets[b + 1]` are
    /// bin b's beams.
    fn sort(self, unbinned: &mut Vec<Beam>, beams: &mut Vec<Beam>, inverse: &mut Vec<Vector3>) {
        let bins = self.bins;
        let offsets = self.offsets;
        offsets.clear();
        offsets.resize(bins + 1, 0);
        let mut in_order = true;
        let mut last = 0;
        for &bin in self.bin_of {
            if (bin as usize) < bins {
                offsets[bin as usize + 1] += 1;
                in_order &= last <= bin;
                last = bin;
            }
        }
        for i in 0..bins {
            offsets[i + 1] += offsets[i];
        }
        let inverse_of = |beam: &Beam| beam.direction.map(|c| 1.0 / c);
        if in_order {
            // The bins lie in the raster's order, so a scan's beams come in
            // bin order unless a beam turns into a bin beyond the next
            // beam's (no grid of the benchmark's or the quickstart's scans
            // has one): the sort is then the input less the beams left out,
            // and the beams stay where they were computed.
            let mut placed = self.bin_of.iter().map(|&bin| (bin as usize) < bins);
            unbinned.retain(|_| placed.next() == Some(true));
            std::mem::swap(beams, unbinned);
            beams.par_iter().map(inverse_of).collect_into_vec(inverse);
        } else {
            self.next.clone_from(offsets);
            self.sorted.clear();
            self.sorted.resize(offsets[bins] as usize, 0);
            for (i, &bin) in self.bin_of.iter().enumerate() {
                if (bin as usize) < bins {
                    let slot = &mut self.next[bin as usize];
                    self.sorted[*slot as usize] = i as u32;
                    *slot += 1;
                }
            }
            // The beams in bin order, each with its inverse direction.
            self.sorted
                .par_iter()
                .map(|&i| {
                    let beam = unbinned[i as usize];
                    (beam, inverse_of(&beam))
                })
                .unzip_into_vecs(beams, inverse);
        }
    }
}

impl LocalGrid {
    /// The grid of `beams` around `origin`; `origin_covariance` is Γ_u (scene
    /// frame); each beam's `σ² = vᵀ Γ_s v` and `σ_o² = vᵀ Γ_u v` (§4.5).
    /// Beams outside the angular bins are left out.
    pub fn new(
        origin: Vector3,
        scene_from_grid: Matrix3,
        azimuth: Axis,
        elevation: Axis,
        max_range: f64,
        ends: &[BeamEnd],
        origin_covariance: &Matrix3,
    ) -> Self {
        Self::from_ends(
            origin,
            scene_from_grid,
            azimuth,
            elevation,
            max_range,
            (ends.len(), |i| Some(ends[i])),
            origin_covariance,
        )
    }

    /// [`LocalGrid::new`] from `(count, end)`: beam `i < count` ends at
    /// `end(i)` (`None`: it carries nothing), computed as it is binned, so
    /// the ends are never held at once.
    pub fn from_ends(
        origin: Vector3,
        scene_from_grid: Matrix3,
        azimuth: Axis,
        elevation: Axis,
        max_range: f64,
        ends: (usize, impl Fn(usize) -> Option<BeamEnd> + Sync),
        origin_covariance: &Matrix3,
    ) -> Self {
        let layout = GridLayout {
            origin,
            scene_from_grid,
            azimuth,
            elevation,
            max_range,
        };
        Self::from_ends_in(
            GridBuffers::default(),
            layout,
            None,
            ends,
            origin_covariance,
        )
    }

    /// [`LocalGrid::from_ends`] in the memory of `buffers` (from
    /// [`LocalGrid::into_buffers`]); the grid is the same. `nominal`, the
    /// bins of the beams' nominal directions on these axes, answers most
    /// beams' bin lookups (the same bins; ignored if made for other axes).
    pub fn from_ends_in(
        buffers: GridBuffers,
        layout: GridLayout,
        nominal: Option<&NominalBins<'_>>,
        (count, end): (usize, impl Fn(usize) -> Option<BeamEnd> + Sync),
        origin_covariance: &Matrix3,
    ) -> Self {
        let GridLayout {
            origin,
            scene_from_grid,
            azimuth,
            elevation,
            max_range,
        } = layout;
        let bins = azimuth.count * elevation.count;
        let slack = lookup::slack(&azimuth, &elevation);
        let tangents = [TangentBins::new(&azimuth), TangentBins::new(&elevation)];
        // Each beam's bin and the beam, in input order; `bins` (one past the
        // last bin) marks a beam left out.
        let GridBuffers {
            mut bin_of,
            mut unbinned,
            mut next,
            mut sorted,
            mut own,
            mut offsets,
            mut beams,
            mut inverse,
            surfaces,
            levels,
        } = buffers;
        let binning = Binning {
            origin,
            origin_covariance,
            grid_from_scene: scene_from_grid.transpose(),
            axes: [&azimuth, &elevation],
            slack,
            tangents: &tangents,
            nominal: nominal.filter(|n| n.fits(&azimuth, &elevation)),
            bins,
        };
        (0..count)
            .into_par_iter()
            .map(|i| binning.bin(i, end(i)))
            .unzip_into_vecs(&mut bin_of, &mut unbinned);
        let sort = BinSort {
            bin_of: &bin_of,
            bins,
            offsets: &mut offsets,
            next: &mut next,
            sorted: &mut sorted,
        };
        sort.sort(&mut unbinned, &mut beams, &mut inverse);
        let spare = GridBuffers {
            bin_of,
            unbinned,
            next,
            sorted,
            ..GridBuffers::default()
        };
        let mut grid = Self {
            origin,
            scene_from_grid,
            azimuth,
            elevation,
            max_range,
            slack,
            tangents,
            offsets,
            beams,
            inverse,
            surfaces,
            levels: Vec::new(),
            samples: Vec::new(),
            sample_inverse: Vec::new(),
            spare,
        };
        let mut levels = levels.into_iter();
        let mut level0 = levels.next().unwrap_or_default();
        grid.build_surfaces_and_level0(&mut own, &mut level0);
        grid.spare.own = own;
        grid.build_pyramid(level0, levels);
        grid
    }

    /// The grid's memory, to build the next grid in
    /// ([`LocalGrid::from_ends_in`]).
    pub fn into_buffers(self) -> GridBuffers {
        GridBuffers {
            offsets: self.offsets,
            // The next grid writes its beams in input order first, and in
            // raster order they become its beams in place (`BinSort`): given
            // these beams' memory for that, a map touches one buffer of
            // beams, not two.
            unbinned: self.beams,
            beams: self.spare.unbinned,
            inverse: self.inverse,
            surfaces: self.surfaces,
            levels: self.levels.into_iter().map(|l| l.cells).collect(),
            ..self.spare
        }
    }

    /// Number of beams held.
    pub fn beam_count(&self) -> usize {
        self.beams.len()
    }

    /// Every beam held, bin by bin, with their inverse directions.
    pub fn beams(&self) -> (&[Beam], &[Vector3]) {
        (&self.beams, &self.inverse)
    }

    /// The beams of angular bin `(a, e)` with their inverse directions.
    #[inline]
    pub fn bin_beams(&self, a: usize, e: usize) -> (&[Beam], &[Vector3]) {
        let i = bin_index(self.azimuth.count, a, e);
        let (lo, hi) = (self.offsets[i] as usize, self.offsets[i + 1] as usize);
        (&self.beams[lo..hi], &self.inverse[lo..hi])
    }

    /// The aggregate of bin `(a, e)`'s own beams (the pyramid's level 0).
    #[inline]
    pub fn bin_summary(&self, a: usize, e: usize) -> &BoxSummary {
        &self.levels[0].cells[bin_index(self.azimuth.count, a, e)]
    }

    /// The nearest surface of bin `(a, e)`: a beam of the bin's own, but at
    /// the smallest range its surface may take anywhere within the bin's solid
    /// angle, so that a point judged by its bin is called free only if it is
    /// in front of the surface across the whole bin (§5.4). `None`: an empty
    /// bin (nothing is known there).
    #[inline]
    pub fn bin_surface(&self, a: usize, e: usize) -> Option<&Surface> {
        self.surfaces[bin_index(self.azimuth.count, a, e)].as_ref()
    }
}

mod lookup;
mod nearest;
mod nominal;
mod pyramid;
mod samples;
mod tangent;

pub use nominal::NominalBins;
pub use pyramid::BoxSummary;
use pyramid::Level;
pub use samples::SAMPLES_PER_BEAM;
#[cfg(test)]
mod tests;
