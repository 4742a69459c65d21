//! One viewpoint's local grid from its propagated beams (docs/math.md §4.5, §5.1).

use super::spherical::{Axis, BeamEnd, GridBuffers, GridLayout, LocalGrid};
use crate::geometry::{Matrix3, Vector3};

/// The angular layout of the scanner: its column and row angles (rad).
#[derive(Clone, Copy, Debug)]
pub struct Raster<'a> {
    /// Horizontal angles, increasing.
    pub horizontal: &'a [f64],
    /// Vertical angles, increasing.
    pub vertical: &'a [f64],
}

fn angle_axis(angles: &[f64], fallback_step: f64) -> Axis {
    let step = if angles.len() >= 2 {
        (angles[angles.len() - 1] - angles[0]) / (angles.len() - 1) as f64
    } else {
        fallback_step
    };
    Axis {
        start: angles[0] - step / 2.0,
        step,
        count: angles.len(),
    }
}

/// Builds the local grid of a viewpoint: one angular bin per raster beam.
///
/// - `origin`, `origin_covariance`: the propagated sensor origin û and Γ_u;
/// - `scene_from_camera`: the nominal rotation of the sensor (sets the grid axes);
/// - `beams`: the propagated ends, scene frame;
/// - `max_range`: how far a no-return beam clears.
pub fn local_grid(
    origin: &Vector3,
    origin_covariance: &Matrix3,
    scene_from_camera: &Matrix3,
    raster: Raster,
    beams: &[BeamEnd],
    max_range: f64,
) -> LocalGrid {
    let (azimuth, elevation) = raster_axes(raster);
    let layout = GridLayout {
        origin: *origin,
        scene_from_grid: scene_from_camera * CAMERA_FROM_GRID,
        azimuth,
        elevation,
        max_range,
    };
    let ends = (beams.len(), |i: usize| Some(beams[i]));
    LocalGrid::from_ends_in(
        GridBuffers::default(),
        layout,
        None,
        ends,
        origin_covariance,
    )
}

/// Grid x = camera z (boresight), grid y = camera x, grid z = camera y.
pub const CAMERA_FROM_GRID: Matrix3 = Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0);

/// The grid's azimuth and elevation axes: one bin per raster column and row.
pub fn raster_axes(raster: Raster) -> (Axis, Axis) {
    let h_step = if raster.horizontal.len() >= 2 {
        raster.horizontal[1] - raster.horizontal[0]
    } else {
        0.01
    };
    let v_step = if raster.vertical.len() >= 2 {
        raster.vertical[1] - raster.vertical[0]
    } else {
        h_step
    };
    (
        angle_axis(raster.horizontal, v_step),
        angle_axis(raster.vertical, h_step),
    )
}

#[cfg(test)]
mod tests;
