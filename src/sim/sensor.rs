//! The laser range scanner: a raster (or a single line) of beams in the
//! `laser` frame, and its range-error model.

use crate::geometry::{Matrix3, Vector3};
use serde::Deserialize;

/// The scanner's geometry as written in an experiment's `[sensor]` table.
///
/// Beams leave the laser origin along
/// `d(h, v) = (cos v · sin h, sin v, cos v · cos h)`: `h` is the horizontal
/// angle (toward +x), `v` the vertical angle (toward +y), and the boresight is +z.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScannerSpec {
    /// Full horizontal field of view (degrees).
    pub horizontal_fov_deg: f64,
    /// Angle between neighbouring beams of a row (degrees).
    pub horizontal_step_deg: f64,
    /// Full vertical field of view (degrees); 0 makes a line scanner.
    #[serde(default)]
    pub vertical_fov_deg: f64,
    /// Angle between rows (degrees); defaults to the horizontal step.
    pub vertical_step_deg: Option<f64>,
    /// Nearest range the scanner reports (m).
    pub min_range: f64,
    /// Farthest range the scanner reports (m).
    pub max_range: f64,
}

/// A scanner ready to cast: its beam directions in the laser frame.
#[derive(Clone, Debug)]
pub struct Scanner {
    /// Unit beam directions, row by row (vertical angle outer).
    pub directions: Vec<Vector3>,
    /// Horizontal angles of the columns (rad), increasing.
    pub horizontal_angles: Vec<f64>,
    /// Vertical angles of the rows (rad), increasing.
    pub vertical_angles: Vec<f64>,
    /// Beams per row.
    pub columns: usize,
    /// Rows.
    pub rows: usize,
    /// Nearest reported range (m).
    pub min_range: f64,
    /// Farthest reported range (m).
    pub max_range: f64,
}

/// Most beams per viewpoint (a 2000 x 2000 raster): beyond it a run's scans
/// and local grids no longer fit in a workstation's memory.
pub const MAX_BEAMS_PER_VIEWPOINT: f64 = 4_000_000.0;

/// Most finest cells the boundary of one viewpoint's cleared space may hold
/// ([`Scanner::check_clearing`]): the uncertainty-aware merge evaluates each
/// (about a microsecond and tens of bytes apiece), so beyond this one map
/// takes minutes and gigabytes.
pub const MAX_CLEARED_BOUNDARY_CELLS: f64 = 1e8;

/// How many angles `angles` gives (as a float, so that absurd steps are
/// caught before anything is allocated).
fn angle_count(fov_deg: f64, step_deg: f64) -> f64 {
    (fov_deg / step_deg + 1e-9).floor() + 1.0
}

/// Angles `-fov/2 ..= fov/2` with the given step, symmetric about 0.
fn angles(fov_deg: f64, step_deg: f64) -> Vec<f64> {
    let n = angle_count(fov_deg, step_deg) as usize;
    let span = (n - 1) as f64 * step_deg;
    (0..n)
        .map(|i| (-span / 2.0 + i as f64 * step_deg).to_radians())
        .collect()
}

impl ScannerSpec {
    /// Checks the numbers and builds the beam raster. Errors are phrased for
    /// the `[sensor]` table.
    pub fn build(&self) -> Result<Scanner, String> {
        let v_step = self.vertical_step_deg.unwrap_or(self.horizontal_step_deg);
        let checks = [
            (
                "horizontal_fov_deg",
                self.horizontal_fov_deg,
                self.horizontal_fov_deg > 0.0 && self.horizontal_fov_deg < 180.0,
            ),
            (
                "horizontal_step_deg",
                self.horizontal_step_deg,
                self.horizontal_step_deg > 0.0,
            ),
            (
                "vertical_fov_deg",
                self.vertical_fov_deg,
                self.vertical_fov_deg >= 0.0 && self.vertical_fov_deg < 180.0,
            ),
            ("vertical_step_deg", v_step, v_step > 0.0),
            ("min_range", self.min_range, self.min_range >= 0.0),
            ("max_range", self.max_range, self.max_range > 0.0),
        ];
        for (name, value, ok) in checks {
            if !value.is_finite() || !ok {
                return Err(format!(
                    "[sensor] {name} = {value} is out of range (fields of view in (0, 180) degrees, \
                     positive steps, 0 <= min_range < max_range)"
                ));
            }
        }
        if self.max_range <= self.min_range {
            return Err(format!(
                "[sensor] max_range = {} must exceed min_range = {}",
                self.max_range, self.min_range
            ));
        }
        let rows = if self.vertical_fov_deg == 0.0 {
            1.0
        } else {
            angle_count(self.vertical_fov_deg, v_step)
        };
        let beams = angle_count(self.horizontal_fov_deg, self.horizontal_step_deg) * rows;
        if beams.is_nan() || beams > MAX_BEAMS_PER_VIEWPOINT {
            return Err(format!(
                "[sensor] these fields of view and steps give {beams:.3e} beams per viewpoint; \
                 sigmap handles at most {MAX_BEAMS_PER_VIEWPOINT:.0} (use larger steps)"
            ));
        }
        let horizontal = angles(self.horizontal_fov_deg, self.horizontal_step_deg);
        let vertical = if self.vertical_fov_deg == 0.0 {
            vec![0.0f64]
        } else {
            angles(self.vertical_fov_deg, v_step)
        };
        let directions = vertical
            .iter()
            .flat_map(|&v| {
                horizontal
                    .iter()
                    .map(move |&h| Vector3::new(v.cos() * h.sin(), v.sin(), v.cos() * h.cos()))
            })
            .collect();
        Ok(Scanner {
            directions,
            columns: horizontal.len(),
            rows: vertical.len(),
            horizontal_angles: horizontal,
            vertical_angles: vertical,
            min_range: self.min_range,
            max_range: self.max_range,
        })
    }
}

impl Scanner {
    /// The finest cells of edge `resolution` on the boundary of the space one
    /// viewpoint clears when none of its beams returns. The boundary is the
    /// surface of the field of view's pyramid out to the maximum range R
    /// (half-angles α, β of the outermost columns and rows), of area `A = R²
    /// (4 tan α tan β + 2 tan α / cos β + 2 tan β / cos α)`; the cells whose
    /// circumscribed ball (radius √3/2 of an edge) meets it fill a layer √3
    /// edges thick: `√3 A / resolution²` cells. Inside, free space is updated
    /// a whole node at a time; these cells one by one.
    pub fn cleared_boundary_cells(&self, resolution: f64) -> f64 {
        let half_angle = |angles: &[f64]| angles.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        let (alpha, beta) = (
            half_angle(&self.horizontal_angles),
            half_angle(&self.vertical_angles),
        );
        let area = self.max_range.powi(2)
            * (4.0 * alpha.tan() * beta.tan()
                + 2.0 * alpha.tan() / beta.cos()
                + 2.0 * beta.tan() / alpha.cos());
        3f64.sqrt() * area / (resolution * resolution)
    }

    /// Checks that a map of `resolution` can be built from this scanner by
    /// the uncertainty-aware methods: at most
    /// [`MAX_CLEARED_BOUNDARY_CELLS`] cells on the boundary of a viewpoint's
    /// cleared space ([`Scanner::cleared_boundary_cells`]).
    pub fn check_clearing(&self, resolution: f64) -> Result<(), String> {
        let cells = self.cleared_boundary_cells(resolution);
        if cells <= MAX_CLEARED_BOUNDARY_CELLS {
            return Ok(());
        }
        let range = self.max_range;
        let range = if range < 1e6 {
            format!("{range}")
        } else {
            format!("{range:e}")
        };
        Err(format!(
            "[sensor] max_range = {range} m at resolution {resolution} m: a viewpoint whose beams \
             all miss clears space bounded by {cells:.2e} cells, which the uncertainty-aware \
             methods evaluate one by one; sigmap handles at most \
             {MAX_CLEARED_BOUNDARY_CELLS:.0e} (lower max_range or use a coarser resolution)"
        ))
    }
}

/// Gaussian range error `σ(r) = σ0 + k r`, optional angular jitter of the true
/// beam direction, optional dropout.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RangeModel {
    /// Constant part of the range standard deviation (m).
    pub sigma0: f64,
    /// Growth of the standard deviation with range (m per m).
    #[serde(default)]
    pub k: f64,
    /// Standard deviation of the beam direction about each of its two
    /// perpendicular axes (radians).
    #[serde(default)]
    pub angular_sigma: f64,
    /// Probability that a beam that hits returns nothing.
    #[serde(default)]
    pub dropout: f64,
}

impl RangeModel {
    /// Checks the numbers; errors are phrased for the `[range]` table.
    pub fn check(&self) -> Result<(), String> {
        // Beyond these a "range sensor" says nothing and the statistics
        // overflow: a metre of noise, a metre per metre, half a radian.
        for (name, value, limit) in [
            ("sigma0", self.sigma0, 1.0),
            ("k", self.k, 1.0),
            ("angular_sigma", self.angular_sigma, 0.5),
        ] {
            if !value.is_finite() || !(0.0..=limit).contains(&value) {
                return Err(format!(
                    "[range] {name} = {value:e} must be between 0 and {limit}"
                ));
            }
        }
        if !(0.0..1.0).contains(&self.dropout) {
            return Err(format!(
                "[range] dropout = {} must be a probability in [0, 1)",
                self.dropout
            ));
        }
        Ok(())
    }

    /// Range standard deviation at range `r`.
    #[inline]
    pub fn sigma(&self, r: f64) -> f64 {
        self.sigma0 + self.k * r
    }

    /// Covariance of the measured point `r d` in the laser frame (docs/math.md §4.5):
    /// `σ_r² d dᵀ + r² σ_a² (I − d dᵀ)` for a unit direction `d`.
    pub fn point_covariance(&self, direction: &Vector3, r: f64) -> Matrix3 {
        self.point_covariance_with(direction, r, self.sigma(r))
    }

    /// The same with the range standard deviation `sr` given (a pooled range).
    pub fn point_covariance_with(&self, direction: &Vector3, r: f64, sr: f64) -> Matrix3 {
        let ddt = direction * direction.transpose();
        ddt * (sr * sr)
            + (Matrix3::identity() - ddt) * (r * r * self.angular_sigma * self.angular_sigma)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> ScannerSpec {
        ScannerSpec {
            horizontal_fov_deg: 60.0,
            horizontal_step_deg: 0.5,
            vertical_fov_deg: 40.0,
            vertical_step_deg: Some(1.0),
            min_range: 0.1,
            max_range: 3.0,
        }
    }

    #[test]
    fn raster_is_symmetric_unit_and_centred_on_boresight() {
        let scanner = spec().build().unwrap();
        assert_eq!(scanner.columns, 121);
        assert_eq!(scanner.rows, 41);
        assert_eq!(scanner.directions.len(), 121 * 41);
        for d in &scanner.directions {
            assert!((d.norm() - 1.0).abs() < 1e-15);
        }
        let centre = scanner.directions[20 * 121 + 60];
        assert!((centre - Vector3::z()).norm() < 1e-15);
        let corner = scanner.directions[0];
        assert!(
            (corner.x - (-20f64).to_radians().cos() * (-30f64).to_radians().sin()).abs() < 1e-15
        );
    }

    #[test]
    fn line_scanner_and_bad_values() {
        let mut line = spec();
        line.vertical_fov_deg = 0.0;
        assert_eq!(line.build().unwrap().rows, 1);
        let mut bad = spec();
        bad.max_range = 0.05;
        assert!(bad.build().unwrap_err().contains("max_range"));
        bad = spec();
        bad.horizontal_step_deg = f64::NAN;
        assert!(bad.build().is_err());
    }

    #[test]
    fn point_covariance_has_range_and_lateral_parts() {
        let model = RangeModel {
            sigma0: 0.001,
            k: 0.002,
            angular_sigma: 0.001,
            dropout: 0.0,
        };
        let d = Vector3::new(0.0, 0.6, 0.8);
        let c = model.point_covariance(&d, 2.0);
        assert!(((d.transpose() * c * d)[0] - 0.005f64.powi(2)).abs() < 1e-15);
        let lateral = Vector3::x();
        assert!(((lateral.transpose() * c * lateral)[0] - 4e-6).abs() < 1e-15);
        assert!(RangeModel {
            dropout: 1.0,
            ..model
        }
        .check()
        .is_err());
        assert!(RangeModel {
            sigma0: -1.0,
            ..model
        }
        .check()
        .is_err());
    }
}
