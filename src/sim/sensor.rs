//! The laser range scanner: a raster (or a single line) of beams in the
//! `laser` frame, and its range-error model.

use crate::geometry::Vector3;
use crate::mapping::scan::{check_clearing, BeamLayout, MAX_BEAMS_PER_VIEWPOINT};
use crate::mapping::viewpoint::Raster;
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
    /// Its beams as a mapper sees them: unit directions row by row
    /// (vertical angle outer), one grid bin per beam.
    pub layout: BeamLayout,
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
        let directions: Vec<Vector3> = vertical
            .iter()
            .flat_map(|&v| {
                horizontal
                    .iter()
                    .map(move |&h| Vector3::new(v.cos() * h.sin(), v.sin(), v.cos() * h.cos()))
            })
            .collect();
        let raster = Raster {
            horizontal: &horizontal,
            vertical: &vertical,
        };
        let layout = BeamLayout::raster(directions, raster);
        Ok(Scanner {
            layout,
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
    /// Unit beam directions, laser frame, row by row (vertical angle outer).
    pub fn directions(&self) -> &[Vector3] {
        &self.layout.directions
    }

    /// Checks that a map of `resolution` can be built from this scanner by
    /// the uncertainty-aware methods ([`check_clearing`]).
    pub fn check_clearing(&self, resolution: f64) -> Result<(), String> {
        let half_angles = self.layout.half_angles.expect("a scanner is a raster");
        check_clearing(half_angles, self.max_range, resolution)
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
        assert_eq!(scanner.directions().len(), 121 * 41);
        for d in scanner.directions() {
            assert!((d.norm() - 1.0).abs() < 1e-15);
        }
        let centre = scanner.directions()[20 * 121 + 60];
        assert!((centre - Vector3::z()).norm() < 1e-15);
        let corner = scanner.directions()[0];
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
}
