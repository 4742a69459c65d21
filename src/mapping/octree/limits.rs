//! How large a tree may be: the key range around the origin, checked before
//! anything large is allocated.

use super::CENTER;

/// Checks that points up to `reach` metres from the origin (on any axis),
/// plus one cell of grid offset, fit in a tree of this resolution (±32768
/// cells around the origin).
pub fn check_span(reach: f64, resolution: f64) -> Result<(), String> {
    if reach.is_finite() && reach + resolution < span(resolution) {
        return Ok(());
    }
    Err(format!(
        "the workspace reaches {reach} m from the scene origin; at resolution {resolution} m \
         the map spans only ±{} m (use a coarser resolution or a smaller workspace)",
        span(resolution)
    ))
}

/// How far a tree of this resolution reaches from the origin on each axis
/// (m): 32 767 cells.
pub fn span(resolution: f64) -> f64 {
    (CENTER - 1) as f64 * resolution
}

/// The finest voxel edges sigmap maps at (m).
pub const RESOLUTIONS: std::ops::RangeInclusive<f64> = 0.001..=1.0;
