//! The bins of a scanner's nominal beam directions, and how far a beam may
//! turn from its nominal direction and stay in the same bin: a lookup that
//! answers most beams of a scan with one squared distance (docs/math.md §5.1).
//!
//! A propagated beam's direction `v` (mean origin to mean end point) differs
//! from the scanner's nominal direction `d` by the propagation's bias and the
//! pooling's shifts, usually microradians against bins of a fraction of a
//! degree. Both bin angles are 1-Lipschitz in the great-circle angle θ
//! between `v` and `d`, azimuth up to `1 / cos el`: `|Δel| ≤ θ` and
//! `|Δaz| ≤ θ / cos(|el_d| + θ)`. So when `d`'s libm angles lie `c_el` and
//! `c_az` inside its bin's edges (less a margin that dwarfs every rounding),
//! any `v` within `θ_max = min(c_el, c_az cos(|el_d| + c_el))` of `d` has
//! `d`'s bin, bit for bit the bin [`super::lookup`] computes. The test is on
//! the chord: `|v − d|² < (θ_max (1 − θ_max²/24))² ≤ (2 sin(θ_max / 2))²`.
//! Anything else (no tangent table, a direction off the grid or near an
//! edge, NaN) goes to the full lookup. The clearances come from the tangent
//! tables (lower bounds, no `atan`), so the table costs a few divisions per
//! beam, once per map.

use super::tangent::TangentBins;
use super::{bin_index, Axis};
use crate::geometry::{Matrix3, Vector3};
use rayon::prelude::*;

/// Margin (rad) taken off each clearance: far above the rounding of libm's
/// angles, of the tabulated edges and of the clearance itself (~1e-15 rad).
const MARGIN: f64 = 1e-9;

/// One nominal direction's bin, and the squared chord within which every
/// direction shares that bin (negative: none). Eight bytes a beam: the
/// table is touched once per map, and fresh pages cost more than its
/// arithmetic.
#[derive(Clone, Copy, Debug)]
struct Entry {
    reach2: f32,
    bin: u32,
}

/// The entry of a direction the table does not decide.
const NONE: Entry = Entry {
    reach2: -1.0,
    bin: u32::MAX,
};

/// The nominal directions of a scanner's beams, in beam order, on the bins
/// of one grid layout.
#[derive(Clone, Debug)]
pub struct NominalBins<'a> {
    azimuth: Axis,
    elevation: Axis,
    /// The directions as given, and the rotation into the grid frame.
    directions: &'a [Vector3],
    grid_from_input: Matrix3,
    entries: Vec<Entry>,
}

impl<'a> NominalBins<'a> {
    /// The bins of `directions` (unit vectors, beam order; in the grid frame
    /// once rotated by `grid_from_input`) on the axes `azimuth` × `elevation`.
    pub fn new(
        directions: &'a [Vector3],
        grid_from_input: Matrix3,
        azimuth: Axis,
        elevation: Axis,
    ) -> Self {
        let tangents = [TangentBins::new(&azimuth), TangentBins::new(&elevation)];
        let entries = directions
            .par_iter()
            .map(|d| entry(&(grid_from_input * d), &tangents, azimuth.count))
            .collect();
        Self {
            azimuth,
            elevation,
            directions,
            grid_from_input,
            entries,
        }
    }

    /// Whether these are the bins of the axes `azimuth` × `elevation`.
    pub fn fits(&self, azimuth: &Axis, elevation: &Axis) -> bool {
        self.azimuth == *azimuth && self.elevation == *elevation
    }

    /// The bin (`bin_index`) of beam
    /// `i`'s direction `v` (grid frame, unit) when `v` lies close enough to
    /// the beam's nominal direction for the bin to be the same; `None`
    /// (undecided) otherwise.
    #[inline]
    pub fn bin_near(&self, i: usize, v: &Vector3) -> Option<u32> {
        let (entry, d) = (self.entries.get(i)?, self.directions.get(i)?);
        let chord2 = (v - self.grid_from_input * d).norm_squared();
        (chord2 < f64::from(entry.reach2)).then_some(entry.bin)
    }
}

/// The entry of the unit direction `d`, from the tangents of its angles
/// (no angle is computed: see [`TangentBins::locate_with_clearance`]).
fn entry(d: &Vector3, tangents: &[TangentBins; 2], azimuth_count: usize) -> Entry {
    // Unit to rounding, and in front (the tangent tables' half-space).
    if !((d.norm_squared() - 1.0).abs() < 1e-12 && d.x > 0.0) {
        return NONE;
    }
    let rho = (d.x * d.x + d.y * d.y).sqrt();
    let (Some((a, c_az)), Some((e, c_el))) = (
        tangents[0].locate_with_clearance(d.y / d.x),
        tangents[1].locate_with_clearance(d.z / rho),
    ) else {
        return NONE;
    };
    let (c_az, c_el) = (c_az - MARGIN, c_el - MARGIN);
    // cos(|el| + c) = cos el cos c − sin|el| sin c ≥ ρ (1 − c²/2) − |z| c.
    let cos_top = rho * (1.0 - 0.5 * c_el * c_el) - d.z.abs() * c_el;
    if !(c_az > 0.0 && c_el > 0.0 && cos_top > 0.0) {
        return NONE;
    }
    // Shrunk once more by a relative margin: the directions are unit only to
    // rounding, and the chord-to-angle relation holds for unit vectors.
    let theta = c_el.min(c_az * cos_top) * (1.0 - 1e-6);
    // The chord 2 sin(θ/2) ≥ θ (1 − θ²/24).
    let chord = theta * (1.0 - theta * theta / 24.0);
    match u32::try_from(bin_index(azimuth_count, a, e)) {
        // In f32, less a millionth (more than its rounding).
        Ok(bin) if bin != u32::MAX => Entry {
            reach2: (chord * chord * (1.0 - 1e-6)) as f32,
            bin,
        },
        _ => NONE,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::spherical::lookup::direction_bin;
    use crate::mapping::spherical::tangent::TangentBins;
    use rand::{Rng, SeedableRng};

    fn axes() -> (Axis, Axis) {
        let step = 0.5f64.to_radians();
        (
            Axis {
                start: -0.6 - step / 2.0,
                step,
                count: 140,
            },
            Axis {
                start: -0.4 - step / 2.0,
                step,
                count: 93,
            },
        )
    }

    fn unit(az: f64, el: f64) -> Vector3 {
        Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
    }

    /// Every decided bin is the full lookup's, for directions scattered at
    /// and just beyond each nominal direction's reach; nominal directions at
    /// bin centres (the raster's) and anywhere in their bins.
    #[test]
    fn a_decided_bin_is_the_full_lookups_bit_for_bit() {
        let (azimuth, elevation) = axes();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(41);
        let directions: Vec<Vector3> = (0..4000)
            .map(|i| {
                let (a, e) = (rng.random_range(0..140), rng.random_range(0..93));
                // Half at the bin centre, half anywhere in (and a few beyond) the bin.
                let (fa, fe) = if i % 2 == 0 {
                    (0.5, 0.5)
                } else {
                    (rng.random_range(-0.01..1.01), rng.random_range(-0.01..1.01))
                };
                unit(
                    azimuth.start + (a as f64 + fa) * azimuth.step,
                    elevation.start + (e as f64 + fe) * elevation.step,
                )
            })
            .collect();
        let nominal = NominalBins::new(&directions, Matrix3::identity(), azimuth, elevation);
        let slack = super::super::lookup::slack(&azimuth, &elevation);
        let tangents = [TangentBins::new(&azimuth), TangentBins::new(&elevation)];
        let full = |v: &Vector3| {
            direction_bin([&azimuth, &elevation], slack, &tangents, v)
                .map(|(a, e)| bin_index(azimuth.count, a, e) as u32)
        };
        let (mut decided, mut near_edge) = (0, 0);
        for (i, d) in directions.iter().enumerate() {
            let reach = f64::from(nominal.entries[i].reach2).max(0.0).sqrt();
            for _ in 0..50 {
                // A random turn of up to 1.2 reach (or a tiny one).
                let scale = if rng.random_bool(0.5) {
                    reach * 1.2
                } else {
                    1e-6
                };
                let turn = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * scale;
                let v = (d + turn).normalize();
                if let Some(bin) = nominal.bin_near(i, &v) {
                    decided += 1;
                    assert_eq!(Some(bin), full(&v), "beam {i}: {d:?} turned to {v:?}");
                } else if (v - d).norm() < 1e-5 {
                    near_edge += 1;
                }
            }
        }
        // Most directions are decided; the undecided tiny turns are the
        // nominal directions within ~1e-5 of an edge (a few per cent of the
        // ones drawn anywhere in their bin).
        assert!(decided > 4000 * 50 * 6 / 10, "decided {decided}");
        assert!(
            near_edge < 4000 * 25 / 20,
            "undecided tiny turns {near_edge}"
        );
        // A nominal direction off the grid or a NaN is never decided.
        let off_grid = [unit(1.4, 0.0)];
        let off = NominalBins::new(&off_grid, Matrix3::identity(), azimuth, elevation);
        assert_eq!(off.bin_near(0, &unit(1.4, 0.0)), None);
        assert_eq!(nominal.bin_near(0, &Vector3::from_element(f64::NAN)), None);
        assert_eq!(nominal.bin_near(directions.len(), &directions[0]), None);
    }

    /// The reach is not needlessly small: a raster direction at its bin's
    /// centre may turn by nearly half a bin (cos el less in azimuth).
    #[test]
    fn a_bin_centre_reaches_nearly_half_a_bin() {
        let (azimuth, elevation) = axes();
        let d = unit(azimuth.centre(70), elevation.centre(46));
        let directions = [d];
        let nominal = NominalBins::new(&directions, Matrix3::identity(), azimuth, elevation);
        let reach = f64::from(nominal.entries[0].reach2).sqrt();
        let half = 0.5 * elevation.step;
        assert!(reach > 0.99 * half && reach < half, "{reach} vs {half}");
    }
}
