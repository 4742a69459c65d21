//! Surface samples between neighbouring beams (docs/math.md §5.4, "Surface
//! samples between beams"; opt-in: `interpolate_beams = true`).
//!
//! A cell that a surface only clips between two beams holds no beam's hit,
//! and the chord model calls it free: on curved objects this is most of the
//! false-free cells that remain. Where four neighbouring beams (a 2 × 2 block
//! of bins) lie on one plane, as the windows' χ² test of §5.5 decides, the
//! surface between them is sampled: [`STEPS`] − 1 points per side, each a
//! beam whose direction, range, σ and σ_o are the bilinear blend of the
//! four's. A sample adds to `H` as a beam does (its chord through a cell);
//! it says nothing about the free side (`F`), which stays the beams'.

use super::{BoxSummary, LocalGrid};
use crate::geometry::{Matrix3, Vector3};
use crate::mapping::chord::{Beam, TAIL};
use crate::mapping::pooling::hits_on_one_plane;
use crate::mapping::settings::SampleGate;
use crate::uncertainty::RangeModel;
use rayon::prelude::*;

/// Samples per beam spacing along each axis of a block: a sample every
/// third of the spacing. The surface they sample is continuous; three steps
/// come within 0.002 of its false-free rate on `paper.toml` (eight: 0.0398,
/// three: 0.0420, two: 0.0444, none: 0.0559; docs/math.md §5.4).
pub const STEPS: usize = 3;

/// The most samples a viewpoint's grid adds per beam: the lattice of
/// `STEPS` per spacing less the beams themselves.
pub const SAMPLES_PER_BEAM: usize = STEPS * STEPS - 1;

impl LocalGrid {
    /// The bin's one beam if it holds exactly one, with a return.
    fn single_hit(&self, a: usize, e: usize) -> Option<&Beam> {
        match self.bin_beams(a, e).0 {
            [beam] if beam.range.is_finite() => Some(beam),
            _ => None,
        }
    }

    /// Whether the 3 × 3 bins around `(a, e)` hold one hit each, all on one
    /// plane (the windows' χ² test at 99%, with each hit's noise as `gate`
    /// gives it from the beam's σ and the sensor's noise `range`).
    fn window_on_one_plane(
        &self,
        a: usize,
        e: usize,
        gate: &SampleGate,
        (range, camera_from_grid): (&RangeModel, &Matrix3),
    ) -> bool {
        let (na, ne) = (self.azimuth.count, self.elevation.count);
        if a == 0 || e == 0 || a + 1 >= na || e + 1 >= ne {
            return false;
        }
        let mut hits = [(Vector3::zeros(), 0.0, 0.0, 0.0); 9];
        for (i, slot) in hits.iter_mut().enumerate() {
            let Some(beam) = self.single_hit(a + i / 3 - 1, e + i % 3 - 1) else {
                return false;
            };
            let sensor_sigma = || range.sigma(&(camera_from_grid * beam.direction), beam.range);
            let (sigma, lateral) =
                gate.noise(beam.range, beam.sigma, sensor_sigma, range.angular_sigma);
            *slot = (beam.direction, beam.range, sigma, lateral);
        }
        hits_on_one_plane(&hits)
    }

    /// Adds the surface samples of every 2 × 2 block of bins that lies in a
    /// window on one plane (any of the four windows centred on its bins
    /// holds it), and widens the bins' summaries by the samples' bands, so
    /// that the merge's shortcuts stay exact. A point on an edge between two
    /// blocks is taken once: by the block whose lower edge it is, or by the
    /// other when that block is not sampled. `range` is the sensor's noise
    /// model, `camera_from_grid` the grid's rotation into the sensor's frame.
    /// Call it once per grid.
    pub fn add_surface_samples(&mut self, gate: &SampleGate, sensor: (&RangeModel, &Matrix3)) {
        let (na, ne) = (self.azimuth.count, self.elevation.count);
        let window = |a: usize, e: usize| self.window_on_one_plane(a, e, gate, sensor);
        // Each block holds one bin of even indices: its window first, since
        // a window on one plane settles the four blocks around its bin.
        let mut even = Vec::new();
        super::per_bin_into(&mut even, (na.div_ceil(2), ne.div_ceil(2)), |a, e| {
            window(2 * a, 2 * e)
        });
        let even_planar = |a: usize, e: usize| even[super::bin_index(na.div_ceil(2), a / 2, e / 2)];
        // The window of another bin matters only to a block whose even
        // bin's window is not on one plane.
        let unsettled = |a: usize, e: usize| {
            (a.saturating_sub(1)..=a.min(na.saturating_sub(2))).any(|ba| {
                (e.saturating_sub(1)..=e.min(ne.saturating_sub(2)))
                    .any(|be| !even_planar(ba + (ba & 1), be + (be & 1)))
            })
        };
        let mut planar = Vec::new();
        super::per_bin_into(&mut planar, (na, ne), |a, e| {
            if a % 2 == 0 && e % 2 == 0 {
                even_planar(a, e)
            } else {
                unsettled(a, e) && window(a, e)
            }
        });
        let sampled = |a: usize, e: usize| {
            a + 1 < na
                && e + 1 < ne
                && [(a, e), (a + 1, e), (a, e + 1), (a + 1, e + 1)]
                    .iter()
                    .any(|&(x, y)| planar[super::bin_index(na, x, y)])
        };
        let rows: Vec<Vec<(usize, Beam)>> = (0..na.saturating_sub(1))
            .into_par_iter()
            .map(|a| {
                let mut row = Vec::new();
                for e in 0..ne.saturating_sub(1) {
                    if sampled(a, e) {
                        self.block_samples(a, e, &sampled, &mut row);
                    }
                }
                row
            })
            .collect();
        let level = &mut self.levels[0];
        for (bin, sample) in rows.into_iter().flatten() {
            let cell = &mut level.cells[bin];
            cell.add(&BoxSummary {
                near: sample.band_start(self.max_range),
                hit_near: f64::INFINITY,
                far: sample.reach(self.max_range),
                origin: TAIL * sample.sigma_origin,
                filled: 0,
                bins: 0,
            });
            self.samples.push(sample);
            self.sample_inverse.push(sample.direction.map(|c| 1.0 / c));
        }
        self.aggregate_levels();
    }

    /// The samples of the block of bins `(a..=a+1, e..=e+1)` (whose four
    /// bins hold one hit each), with the bin each falls in, into `out`.
    fn block_samples(
        &self,
        a: usize,
        e: usize,
        sampled: &impl Fn(usize, usize) -> bool,
        out: &mut Vec<(usize, Beam)>,
    ) {
        let corner = |da: usize, de: usize| self.single_hit(a + da, e + de);
        let (Some(b00), Some(b10), Some(b01), Some(b11)) =
            (corner(0, 0), corner(1, 0), corner(0, 1), corner(1, 1))
        else {
            return;
        };
        let corners = [b00, b10, b01, b11];
        // The upper edges belong to the next block unless it is not sampled.
        let last_a = if sampled(a + 1, e) { STEPS - 1 } else { STEPS };
        let last_e = if sampled(a, e + 1) { STEPS - 1 } else { STEPS };
        for i in 0..=last_a {
            for j in 0..=last_e {
                if (i == 0 || i == STEPS) && (j == 0 || j == STEPS) {
                    continue;
                }
                let (u, v) = (i as f64 / STEPS as f64, j as f64 / STEPS as f64);
                let w = [(1.0 - u) * (1.0 - v), u * (1.0 - v), (1.0 - u) * v, u * v];
                let blend = |f: &dyn Fn(&Beam) -> f64| -> f64 {
                    corners.iter().zip(w).map(|(b, w)| w * f(b)).sum()
                };
                let direction = corners
                    .iter()
                    .zip(w)
                    .fold(Vector3::zeros(), |s, (b, w)| s + b.direction * w)
                    .normalize();
                let sample = Beam {
                    direction,
                    range: blend(&|b| b.range),
                    sigma: blend(&|b| b.sigma),
                    sigma_origin: blend(&|b| b.sigma_origin),
                };
                if let Some((sa, se)) = self.bin_of(&(self.origin + direction)) {
                    out.push((super::bin_index(self.azimuth.count, sa, se), sample));
                }
            }
        }
    }

    /// The surface samples with their inverse directions (empty unless
    /// [`LocalGrid::add_surface_samples`] ran).
    pub fn samples(&self) -> (&[Beam], &[Vector3]) {
        (&self.samples, &self.sample_inverse)
    }
}

#[cfg(test)]
mod tests;
