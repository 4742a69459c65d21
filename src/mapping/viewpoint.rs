//! One viewpoint's local grid from its propagated beams (docs/math.md §4.5, §5.1).

use super::spherical::{Axis, BeamEnd, GridBuffers, GridLayout, LocalGrid, NominalBins};
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
    let ends = (beams.len(), |i: usize| Some(beams[i]));
    local_grid_of(
        GridBuffers::default(),
        (origin, origin_covariance),
        scene_from_camera,
        (raster, None),
        ends,
        max_range,
    )
}

/// [`local_grid`] from `(count, end)`: beam `i < count` ends at `end(i)`,
/// computed as it is binned ([`LocalGrid::from_ends_in`]), in the memory of
/// `buffers`; `nominal` ([`nominal_bins`] of the same raster) speeds up the
/// binning without changing it.
pub fn local_grid_of(
    buffers: GridBuffers,
    (origin, origin_covariance): (&Vector3, &Matrix3),
    scene_from_camera: &Matrix3,
    (raster, nominal): (Raster, Option<&NominalBins<'_>>),
    ends: (usize, impl Fn(usize) -> Option<BeamEnd> + Sync),
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
    LocalGrid::from_ends_in(buffers, layout, nominal, ends, origin_covariance)
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

/// The bins of the scanner's nominal beam directions (camera frame, beam
/// order) on the grid of `raster`: computed once per map, they answer most
/// beams' bin lookups in every viewpoint's grid ([`NominalBins`]).
pub fn nominal_bins<'a>(raster: Raster, camera_directions: &'a [Vector3]) -> NominalBins<'a> {
    let (azimuth, elevation) = raster_axes(raster);
    NominalBins::new(
        camera_directions,
        CAMERA_FROM_GRID.transpose(),
        azimuth,
        elevation,
    )
}

#[cfg(test)]
mod tests;
