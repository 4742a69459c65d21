//! How large a tree may be: the key range around the origin and the cells a
//! workspace may hold, checked before anything large is allocated.

use super::CENTER;

/// Checks that points up to `reach` metres from the origin (on any axis),
/// plus one cell of grid offset, fit in a tree of this resolution (±32768
/// cells around the origin).
pub fn check_span(reach: f64, resolution: f64) -> Result<(), String> {
    if reach.is_finite() && reach + resolution < (CENTER - 1) as f64 * resolution {
        return Ok(());
    }
    Err(format!(
        "the workspace reaches {reach} m from the scene origin; at resolution {resolution} m \
         the map spans only ±{} m (use a coarser resolution or a smaller workspace)",
        (CENTER - 1) as f64 * resolution
    ))
}

/// Most cells a workspace may hold at the map's resolution (the ground
/// truth and the observable mask walk them: about 2 minutes at 2³¹).
pub const MAX_WORKSPACE_CELLS: f64 = 2_147_483_648.0;

/// The finest voxel edges sigmap maps at (m).
pub const RESOLUTIONS: std::ops::RangeInclusive<f64> = 0.001..=1.0;

/// Checks that a workspace of `extent` metres per axis holds at most
/// [`MAX_WORKSPACE_CELLS`] cells of edge `resolution`.
pub fn check_cells(extent: [f64; 3], resolution: f64) -> Result<(), String> {
    let cells: f64 = extent.iter().map(|e| (e / resolution).ceil()).product();
    if cells <= MAX_WORKSPACE_CELLS {
        return Ok(());
    }
    Err(format!(
        "the workspace holds {cells:.3e} cells of {resolution} m; sigmap handles at most \
         {MAX_WORKSPACE_CELLS:.3e} (use a coarser resolution or a smaller workspace)"
    ))
}
