//! Depth images with a trajectory, in the layout of the TUM RGB-D benchmark
//! (and of the datasets that follow it: ICL-NUIM, ETH3D SLAM, Bonn RGB-D),
//! as recorded scans: each depth image a node, its pixels the node's points.
//!
//! ```text
//! depth.txt         # timestamp filename            one line per image
//!                   1305031102.160407 depth/1305031102.160407.png
//! groundtruth.txt   # timestamp tx ty tz qx qy qz qw   the camera's pose in
//!                   1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248
//! depth/*.png       16-bit grayscale, depth × scale (5000 per metre); 0: none
//! ```
//!
//! A pixel `(u, v)` (column, row, from 0) of raw depth `d > 0` is the point
//! `Z = d / scale`, `X = (u − c_x) Z / f_x`, `Y = (v − c_y) Z / f_y` in the
//! camera frame (x right, y down, z forward: sigmap's sensor frame), as the
//! benchmark's own `generate_pointcloud.py` has it. Each image takes the
//! trajectory pose nearest its timestamp, if within [`MAX_TIME_GAP`] (the
//! benchmark's `associate.py` default); the pose maps camera coordinates to
//! the trajectory's frame, the map frame.

use super::scan::PixelRaster;
use super::scan_graph::ScanNode;
use super::scan_log::shown;
use crate::geometry::{Isometry3, Point3};
use nalgebra::{Quaternion, Translation3, UnitQuaternion};

/// The farthest an image's timestamp may lie from its pose's (s).
pub const MAX_TIME_GAP: f64 = 0.02;

/// A pinhole depth camera: focal lengths and principal point in pixels,
/// and the raw depth value of one metre.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DepthCamera {
    /// Focal lengths (px).
    pub fx: f64,
    /// Focal lengths (px).
    pub fy: f64,
    /// Principal point (px).
    pub cx: f64,
    /// Principal point (px).
    pub cy: f64,
    /// Raw depth per metre.
    pub scale: f64,
}

impl DepthCamera {
    /// The benchmark's depth camera (the ROS defaults its tools use for
    /// every Kinect sequence): 525, 525, 319.5, 239.5, 5000 per metre.
    pub const TUM: DepthCamera = DepthCamera {
        fx: 525.0,
        fy: 525.0,
        cx: 319.5,
        cy: 239.5,
        scale: 5000.0,
    };

    /// Checks the numbers: finite, nonzero focal lengths (a negative one
    /// flips its axis, as ICL-NUIM's `f_y` does), a positive scale.
    pub fn check(&self) -> Result<(), String> {
        let numbers = [self.fx, self.fy, self.cx, self.cy, self.scale];
        if numbers.iter().any(|v| !v.is_finite()) || self.fx == 0.0 || self.fy == 0.0 {
            return Err(format!(
                "--intrinsics {},{},{},{}: give four finite numbers fx,fy,cx,cy (pixels) with \
                 nonzero focal lengths",
                self.fx, self.fy, self.cx, self.cy
            ));
        }
        if self.scale <= 0.0 {
            return Err(format!(
                "--depth-scale {}: give the positive raw depth of one metre (5000 for TUM)",
                self.scale
            ));
        }
        Ok(())
    }

    /// The angular bin width of the OPDF grids for this camera's images
    /// (rad): `1 / min(|f_x|, |f_y|)`, the angle of a pixel at the image's
    /// centre, the widest any pixel spans (docs/math.md §5.6, "Depth
    /// images"): no bin inside the image is left empty.
    pub fn angular_step(&self) -> f64 {
        1.0 / self.fx.abs().min(self.fy.abs())
    }

    /// The camera-frame point of pixel `(u, v)` with raw depth `raw`; `None`
    /// for 0 (no measurement).
    #[inline]
    pub fn point(&self, u: usize, v: usize, raw: u16) -> Option<Point3> {
        (raw > 0).then(|| {
            let z = f64::from(raw) / self.scale;
            Point3::new(
                (u as f64 - self.cx) * z / self.fx,
                (v as f64 - self.cy) * z / self.fy,
                z,
            )
        })
    }
}

/// The `timestamp rest…` lines of a benchmark list: `#` comments and blank
/// lines skipped; each line's timestamp and its other fields. An error
/// names the line (1-based).
fn timestamped_lines(text: &str) -> impl Iterator<Item = Result<(usize, f64, Vec<&str>), String>> {
    text.lines().enumerate().filter_map(|(k, line)| {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            return None;
        }
        let mut fields = line.split_whitespace();
        let stamp = fields.next().unwrap_or_default();
        let parsed = match stamp.parse::<f64>() {
            Ok(t) if t.is_finite() => Ok((k + 1, t, fields.collect())),
            _ => Err(format!(
                "line {}: '{}' is not a timestamp (seconds)",
                k + 1,
                shown(stamp)
            )),
        };
        Some(parsed)
    })
}

/// The images of a `depth.txt` (`timestamp filename` lines), in file order.
pub fn parse_depth_list(text: &str) -> Result<Vec<(f64, String)>, String> {
    timestamped_lines(text)
        .map(|line| {
            let (number, stamp, fields) = line?;
            match fields[..] {
                [file] => Ok((stamp, file.to_string())),
                _ => Err(format!(
                    "line {number}: expected `timestamp filename`, found {} fields after the \
                     timestamp",
                    fields.len()
                )),
            }
        })
        .collect()
}

/// The poses of a trajectory (`timestamp tx ty tz qx qy qz qw` lines), in
/// file order. A quaternion is normalised if its norm is within 1% of 1
/// (files round them), refused otherwise.
pub fn parse_trajectory(text: &str) -> Result<Vec<(f64, Isometry3)>, String> {
    timestamped_lines(text)
        .map(|line| {
            let (number, stamp, fields) = line?;
            let values: Vec<f64> = fields
                .iter()
                .map(|f| f.parse::<f64>().ok().filter(|v| v.is_finite()))
                .collect::<Option<_>>()
                .ok_or_else(|| format!("line {number}: a field is not a finite number"))?;
            let [tx, ty, tz, qx, qy, qz, qw] = values[..] else {
                return Err(format!(
                    "line {number}: expected `timestamp tx ty tz qx qy qz qw`, found {} numbers \
                     after the timestamp",
                    values.len()
                ));
            };
            let q = Quaternion::new(qw, qx, qy, qz);
            if (q.norm() - 1.0).abs() > 0.01 {
                return Err(format!(
                    "line {number}: the quaternion (qx qy qz qw) = ({qx} {qy} {qz} {qw}) has norm \
                     {:.4}, not 1",
                    q.norm()
                ));
            }
            let pose = Isometry3::from_parts(
                Translation3::new(tx, ty, tz),
                UnitQuaternion::from_quaternion(q),
            );
            Ok((stamp, pose))
        })
        .collect()
}

/// For each image time of `images`, the index of the pose of `poses` nearest
/// it, if within [`MAX_TIME_GAP`] (the earlier pose on a tie).
pub fn associate(images: &[f64], poses: &[(f64, Isometry3)]) -> Vec<Option<usize>> {
    let mut order: Vec<usize> = (0..poses.len()).collect();
    order.sort_by(|&a, &b| poses[a].0.total_cmp(&poses[b].0).then(a.cmp(&b)));
    images
        .iter()
        .map(|&t| {
            let after = order.partition_point(|&k| poses[k].0 < t);
            [after.checked_sub(1), Some(after)]
                .into_iter()
                .flatten()
                .filter_map(|i| order.get(i).copied())
                .map(|k| ((poses[k].0 - t).abs(), k))
                .filter(|&(gap, _)| gap <= MAX_TIME_GAP)
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(_, k)| k)
        })
        .collect()
}

/// The node of the depth image `bytes` (a 16-bit grayscale PNG) seen by
/// `camera` from `map_from_sensor`: one point per pixel with a depth, row
/// by row.
pub fn depth_image_node(
    bytes: &[u8],
    camera: &DepthCamera,
    id: u32,
    map_from_sensor: Isometry3,
) -> Result<ScanNode, String> {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .map_err(|e| format!("not a PNG image: {e}"))?;
    let info = reader.info();
    let (width, height) = (info.width as usize, info.height as usize);
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(format!(
            "a {:?} {}-bit image; a depth image is 16-bit grayscale",
            info.color_type, info.bit_depth as u8
        ));
    }
    if width as u64 * height as u64 > u64::from(u32::MAX) {
        return Err(format!("{width} x {height} pixels: the image is too large"));
    }
    let size = reader
        .output_buffer_size()
        .ok_or("the image is too large")?;
    let mut raw = vec![0; size];
    let frame = reader
        .next_frame(&mut raw)
        .map_err(|e| format!("cannot decode the image: {e}"))?;
    let stride = frame.line_size;
    let (mut points, mut slots) = (Vec::new(), Vec::new());
    for v in 0..height {
        for u in 0..width {
            // PNG stores 16-bit samples big-endian.
            let at = v * stride + 2 * u;
            if let Some(p) = camera.point(u, v, u16::from_be_bytes([raw[at], raw[at + 1]])) {
                points.push(p);
                // Below 2³² (checked above).
                slots.push((v * width + u) as u32);
            }
        }
    }
    Ok(ScanNode {
        id,
        map_from_sensor,
        points,
        pixels: Some(PixelRaster {
            columns: width,
            rows: height,
            slots,
        }),
    })
}

/// A 16-bit grayscale PNG of `width` columns holding `depths` row by row:
/// the image a depth camera's driver writes (`sigmap export` of a pinhole
/// sensor's scans).
pub fn depth_png(width: u32, depths: &[u16]) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    let height = depths.len() as u32 / width.max(1);
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    let data: Vec<u8> = depths.iter().flat_map(|d| d.to_be_bytes()).collect();
    let encoded = encoder.write_header().and_then(|mut writer| {
        writer
            .write_image_data(&data)
            .and_then(|()| writer.finish())
    });
    encoded.map_err(|e| format!("a {width} x {height} depth image: {e}"))?;
    Ok(bytes)
}

#[cfg(test)]
mod tests;
