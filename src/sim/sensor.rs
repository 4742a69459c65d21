//! The range sensor: a laser scanner's raster (or single line) of beams, or
//! a depth camera's pinhole image, in the `laser` frame.

use crate::geometry::{Point3, Vector3};
use crate::mapping::cloud_grids::cloud_grids;
use crate::mapping::depth_images::DepthCamera;
use crate::mapping::scan::{check_clearing, BeamLayout, PixelRaster, MAX_BEAMS_PER_VIEWPOINT};
use crate::mapping::viewpoint::Raster;
use serde::Deserialize;

/// The kind of range sensor.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SensorModel {
    /// A laser scanner: beams at even angular steps.
    #[default]
    Raster,
    /// A depth camera: one beam through the centre of each pixel of a
    /// pinhole image with square pixels, the principal point at the
    /// image's centre.
    Pinhole,
}

/// The sensor's geometry as written in an experiment's `[sensor]` table.
///
/// A raster's beams leave the laser origin along
/// `d(h, v) = (cos v · sin h, sin v, cos v · cos h)`: `h` is the horizontal
/// angle (toward +x), `v` the vertical angle (toward +y), and the boresight
/// is +z. A pinhole's beam of pixel (column u, row v) leaves along
/// `(u + ½ − W/2, v + ½ − H/2, f)` normalised, `f = (W/2) / tan(fov/2)`:
/// columns toward +x, rows toward +y, as the raster's.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScannerSpec {
    /// A laser scanner's raster (the default) or a depth camera's pinhole.
    #[serde(default)]
    pub model: SensorModel,
    /// Full horizontal field of view (degrees).
    pub horizontal_fov_deg: f64,
    /// Angle between neighbouring beams of a row (degrees); a raster's only.
    #[serde(default)]
    pub horizontal_step_deg: Option<f64>,
    /// Pixels a row; a pinhole's only.
    #[serde(default)]
    pub width: Option<usize>,
    /// Rows of pixels; a pinhole's only.
    #[serde(default)]
    pub height: Option<usize>,
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
    /// (vertical angle outer); a raster's one grid bin per beam, a
    /// pinhole's binned as a recorded cloud's, pooled on its pixels.
    pub layout: BeamLayout,
    /// Horizontal angles of the columns (rad), increasing (a pinhole's
    /// along its centre row).
    pub horizontal_angles: Vec<f64>,
    /// Vertical angles of the rows (rad), increasing (a pinhole's along
    /// its centre column).
    pub vertical_angles: Vec<f64>,
    /// Beams per row.
    pub columns: usize,
    /// Rows.
    pub rows: usize,
    /// Nearest reported range (m).
    pub min_range: f64,
    /// Farthest reported range (m).
    pub max_range: f64,
    /// A pinhole's intrinsics, as its depth images are written
    /// (`sigmap export`): pixel (u, v) with raw depth `d` is the point
    /// `((u − cx) z / fx, (v − cy) z / fy, z)`, `z = d / scale`. `None` for
    /// a raster.
    pub camera: Option<DepthCamera>,
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
    /// Checks the numbers and builds the beams. Errors are phrased for the
    /// `[sensor]` table.
    pub fn build(&self) -> Result<Scanner, String> {
        let misplaced = match self.model {
            SensorModel::Raster => [
                ("width", self.width.is_some()),
                ("height", self.height.is_some()),
            ],
            SensorModel::Pinhole => [
                ("horizontal_step_deg", self.horizontal_step_deg.is_some()),
                (
                    "vertical_fov_deg or vertical_step_deg",
                    self.vertical_fov_deg != 0.0 || self.vertical_step_deg.is_some(),
                ),
            ],
        };
        if let Some((name, _)) = misplaced.iter().find(|(_, given)| *given) {
            let (model, other) = match self.model {
                SensorModel::Raster => ("a raster scanner", "model = \"pinhole\""),
                SensorModel::Pinhole => ("a pinhole camera", "the raster scanner"),
            };
            return Err(format!(
                "[sensor] {name} does not apply to {model} (it belongs to {other})"
            ));
        }
        match self.model {
            SensorModel::Raster => self.build_raster(),
            SensorModel::Pinhole => self.build_pinhole(),
        }
    }

    /// Checks the ranges common to both models.
    fn check_ranges(&self) -> Result<(), String> {
        for (name, value, ok) in [
            ("min_range", self.min_range, self.min_range >= 0.0),
            ("max_range", self.max_range, self.max_range > 0.0),
        ] {
            if !value.is_finite() || !ok {
                return Err(format!(
                    "[sensor] {name} = {value} is out of range (0 <= min_range < max_range)"
                ));
            }
        }
        if self.max_range <= self.min_range {
            return Err(format!(
                "[sensor] max_range = {} must exceed min_range = {}",
                self.max_range, self.min_range
            ));
        }
        Ok(())
    }

    /// A depth camera's pinhole image: one beam per pixel, row by row.
    fn build_pinhole(&self) -> Result<Scanner, String> {
        self.check_ranges()?;
        let fov = self.horizontal_fov_deg;
        if !(fov.is_finite() && fov > 0.0 && fov < 180.0) {
            return Err(format!(
                "[sensor] horizontal_fov_deg = {fov} is out of range (0, 180) degrees"
            ));
        }
        let (Some(width), Some(height)) = (self.width, self.height) else {
            return Err(
                "[sensor] a pinhole camera needs width and height (pixels a row, rows)".into(),
            );
        };
        let pixels = width as f64 * height as f64;
        if width == 0 || height == 0 || pixels > MAX_BEAMS_PER_VIEWPOINT {
            return Err(format!(
                "[sensor] width = {width}, height = {height}: the image must have between 1 and \
                 {MAX_BEAMS_PER_VIEWPOINT:.0} pixels"
            ));
        }
        let focal = width as f64 / 2.0 / (fov / 2.0).to_radians().tan();
        let offset = |i: usize, n: usize| (i as f64 + 0.5 - n as f64 / 2.0) / focal;
        let directions: Vec<Vector3> = (0..height)
            .flat_map(|row| {
                (0..width).map(move |column| {
                    Vector3::new(offset(column, width), offset(row, height), 1.0).normalize()
                })
            })
            .collect();
        let points: Vec<Point3> = directions.iter().map(|d| Point3::from(*d)).collect();
        // Bins one pixel wide at the image's centre (the pixels crowd toward
        // its sides, two to a bin near them: pooling uses the pixels).
        let grids = cloud_grids(&points, Some(1.0 / focal))?;
        let angles = |n: usize| -> Vec<f64> { (0..n).map(|i| offset(i, n).atan()).collect() };
        let (horizontal, vertical) = (angles(width), angles(height));
        let half_angles = Some([horizontal[width - 1], vertical[height - 1]]);
        let layout = BeamLayout {
            directions,
            grids,
            half_angles,
            pixels: Some(PixelRaster {
                columns: width,
                rows: height,
                slots: (0..width * height).map(|k| k as u32).collect(),
            }),
        };
        let camera = DepthCamera {
            fx: focal,
            fy: focal,
            cx: width as f64 / 2.0 - 0.5,
            cy: height as f64 / 2.0 - 0.5,
            scale: depth_scale(self.max_range),
        };
        Ok(Scanner {
            layout,
            columns: width,
            rows: height,
            horizontal_angles: horizontal,
            vertical_angles: vertical,
            min_range: self.min_range,
            max_range: self.max_range,
            camera: Some(camera),
        })
    }

    /// A laser scanner's raster of even angular steps.
    fn build_raster(&self) -> Result<Scanner, String> {
        let Some(h_step) = self.horizontal_step_deg else {
            return Err(
                "[sensor] a raster scanner needs horizontal_step_deg (the angle between the \
                 beams of a row), or model = \"pinhole\" with width and height"
                    .into(),
            );
        };
        let v_step = self.vertical_step_deg.unwrap_or(h_step);
        let checks = [
            (
                "horizontal_fov_deg",
                self.horizontal_fov_deg,
                self.horizontal_fov_deg > 0.0 && self.horizontal_fov_deg < 180.0,
            ),
            ("horizontal_step_deg", h_step, h_step > 0.0),
            (
                "vertical_fov_deg",
                self.vertical_fov_deg,
                self.vertical_fov_deg >= 0.0 && self.vertical_fov_deg < 180.0,
            ),
            ("vertical_step_deg", v_step, v_step > 0.0),
        ];
        for (name, value, ok) in checks {
            if !value.is_finite() || !ok {
                return Err(format!(
                    "[sensor] {name} = {value} is out of range (fields of view in (0, 180) degrees, \
                     positive steps)"
                ));
            }
        }
        self.check_ranges()?;
        let rows = if self.vertical_fov_deg == 0.0 {
            1.0
        } else {
            angle_count(self.vertical_fov_deg, v_step)
        };
        let beams = angle_count(self.horizontal_fov_deg, h_step) * rows;
        if beams.is_nan() || beams > MAX_BEAMS_PER_VIEWPOINT {
            return Err(format!(
                "[sensor] these fields of view and steps give {beams:.3e} beams per viewpoint; \
                 sigmap handles at most {MAX_BEAMS_PER_VIEWPOINT:.0} (use larger steps)"
            ));
        }
        let horizontal = angles(self.horizontal_fov_deg, h_step);
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
            camera: None,
        })
    }
}

/// The raw depth of one metre in a pinhole's 16-bit depth images: the TUM
/// benchmark's 5000 (0.2 mm steps, up to 13.1 m), fewer where the maximum
/// range would overflow 16 bits.
fn depth_scale(max_range: f64) -> f64 {
    (f64::from(u16::MAX) / max_range)
        .floor()
        .clamp(1.0, DepthCamera::TUM.scale)
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
            model: SensorModel::Raster,
            horizontal_fov_deg: 60.0,
            horizontal_step_deg: Some(0.5),
            width: None,
            height: None,
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

    fn pinhole(width: usize, height: usize) -> ScannerSpec {
        ScannerSpec {
            model: SensorModel::Pinhole,
            horizontal_step_deg: None,
            vertical_fov_deg: 0.0,
            vertical_step_deg: None,
            width: Some(width),
            height: Some(height),
            ..spec()
        }
    }

    #[test]
    fn a_pinhole_beam_leaves_through_its_pixel_centre() {
        // 60 degrees across 40 pixels: f = 20 / tan 30°.
        let scanner = pinhole(40, 30).build().unwrap();
        let focal = 20.0 / 30f64.to_radians().tan();
        assert_eq!((scanner.columns, scanner.rows), (40, 30));
        let layout = &scanner.layout;
        let pixels = layout.pixels.as_ref().expect("pooled on its pixels");
        assert_eq!((pixels.columns, pixels.rows), (40, 30));
        for (k, d) in scanner.directions().iter().enumerate() {
            assert!((d.norm() - 1.0).abs() < 1e-15);
            // Projected back through the pinhole: the pixel's centre.
            let (u, v) = (d.x / d.z * focal + 20.0, d.y / d.z * focal + 15.0);
            let (row, column) = (k / 40, k % 40);
            assert!((u - (column as f64 + 0.5)).abs() < 1e-12, "{k}: u {u}");
            assert!((v - (row as f64 + 0.5)).abs() < 1e-12, "{k}: v {v}");
            assert_eq!(pixels.slots[k] as usize, k);
        }
        // The outermost pixel centres bound the space one view clears.
        let [alpha, beta] = layout.half_angles.unwrap();
        assert!((alpha - (19.5 / focal).atan()).abs() < 1e-15);
        assert!((beta - (14.5 / focal).atan()).abs() < 1e-15);
        // One angular grid, bins a centre pixel wide, every beam binned.
        let [grid] = &layout.grids[..] else {
            panic!("{} grids", layout.grids.len())
        };
        assert!((grid.azimuth.step - 1.0 / focal).abs() < 1e-15);
        assert_eq!(grid.len(layout), 40 * 30);
        // Its depth images' intrinsics give each pixel its beam back.
        let camera = scanner.camera.unwrap();
        assert_eq!(camera.scale, 5000.0, "3 m fits 16 bits at 0.2 mm");
        for (k, d) in scanner.directions().iter().enumerate() {
            let p = camera.point(k % 40, k / 40, 5000).unwrap();
            assert!((p.coords.normalize() - d).norm() < 1e-12, "{k}");
        }
        let mut far = pinhole(40, 30);
        far.max_range = 20.0;
        assert_eq!(far.build().unwrap().camera.unwrap().scale, 3276.0);
    }

    #[test]
    fn a_pinhole_and_a_raster_refuse_each_others_fields() {
        let e = |spec: ScannerSpec| spec.build().unwrap_err();
        let mut stepped = pinhole(40, 30);
        stepped.horizontal_step_deg = Some(0.5);
        assert!(e(stepped).contains("horizontal_step_deg does not apply to a pinhole"));
        let mut sized = spec();
        sized.width = Some(40);
        assert!(e(sized).contains("width does not apply to a raster scanner"));
        let mut heightless = pinhole(40, 30);
        heightless.height = None;
        assert!(e(heightless).contains("needs width and height"));
        let mut stepless = spec();
        stepless.horizontal_step_deg = None;
        assert!(e(stepless).contains("needs horizontal_step_deg"));
        // Refused before a beam is allocated.
        assert!(e(pinhole(1 << 20, 1 << 20)).contains("between 1 and"));
        assert!(e(pinhole(0, 30)).contains("between 1 and"));
        let mut wide = pinhole(40, 30);
        wide.horizontal_fov_deg = 180.0;
        assert!(e(wide).contains("horizontal_fov_deg = 180"));
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
        bad.horizontal_step_deg = Some(f64::NAN);
        assert!(bad.build().is_err());
    }
}
