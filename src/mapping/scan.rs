//! What a mapper sees of one viewpoint, whatever made it (a simulated run
//! or a recorded ScanGraph): the measurements, the believed chain with its
//! covariances, and the layout of the beams; and [`MapperView`], what it
//! knows of the sensor and the map. Neither can hold the truth: `sim` keeps
//! it in types of its own, which the mapping layer never names.

use super::spherical::Axis;
use super::viewpoint::{raster_axes, Raster, CAMERA_FROM_GRID};
use super::MapSettings;
use crate::error::metres;
use crate::geometry::{Isometry3, Matrix3, Vector3};
use crate::uncertainty::{RangeModel, SigmaSet, UncertainPose};

/// Most beams per viewpoint (a 2000 x 2000 raster): beyond it a run's scans
/// and local grids no longer fit in a workstation's memory.
pub const MAX_BEAMS_PER_VIEWPOINT: f64 = 4_000_000.0;

/// The modeller's belief about the chain `X_s = T_sw⁻¹ T_rw T_cr X_c`:
/// nominal poses and their covariances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NominalChain {
    /// T_sw: the scene in the world.
    pub world_from_scene: UncertainPose,
    /// T_rw: the robot flange in the world.
    pub world_from_robot: UncertainPose,
    /// T_cr: the laser on the flange.
    pub robot_from_camera: UncertainPose,
}

impl NominalChain {
    /// The nominal `scene_from_camera = T_sw⁻¹ T_rw T_cr`.
    pub fn scene_from_camera(&self) -> Isometry3 {
        self.world_from_scene.mean.to_isometry().inverse()
            * self.world_from_robot.mean.to_isometry()
            * self.robot_from_camera.mean.to_isometry()
    }
}

/// Why a beam has no range.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BeamStatus {
    /// A measured range.
    Hit,
    /// Nothing within the maximum range (a miss, or a surface too far).
    NoReturn,
    /// The surface is nearer than the minimum range.
    TooClose,
    /// The beam hit but the sensor dropped it.
    Dropout,
}

impl BeamStatus {
    /// The word used in files.
    pub fn as_str(self) -> &'static str {
        match self {
            BeamStatus::Hit => "hit",
            BeamStatus::NoReturn => "no_return",
            BeamStatus::TooClose => "too_close",
            BeamStatus::Dropout => "dropout",
        }
    }
}

/// One beam as the sensor reports it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    /// What happened.
    pub status: BeamStatus,
    /// The measured range (m); NaN unless `status` is `Hit`, or a
    /// `NoReturn` recorded as a point beyond the maximum range (OctoMap's
    /// update carves toward it up to that range).
    pub range: f64,
}

/// One viewpoint's scan: all a mapper may see of it. The truth behind it
/// is kept by the simulator in a type of its own, which map building never
/// receives (the mapping layer cannot import `sim`).
#[derive(Clone, Debug)]
pub struct Scan {
    /// Viewpoint index within the experiment.
    pub viewpoint: usize,
    /// Nominal joint configuration.
    pub joints: Vec<f64>,
    /// The believed chain with covariances.
    pub chain: NominalChain,
    /// One measurement per beam of the scanner, in its order.
    pub measurements: Vec<Measurement>,
}

/// How a scan's beams lie: their unit directions in the camera frame (one
/// per measurement, in its order) and the angular grids that bin them for
/// the OPDF merge (docs/math.md §5.1; a recorded cloud's, §5.6).
#[derive(Clone, Debug)]
pub struct BeamLayout {
    /// Unit beam directions, camera frame (zero for a point at the origin,
    /// which no grid holds).
    pub directions: Vec<Vector3>,
    /// The grids the beams are binned on; a beam is in at most one.
    pub grids: Vec<BeamGrid>,
    /// A raster scanner's half-angles of its outermost columns and rows
    /// (rad), which bound the space one viewpoint clears
    /// ([`cleared_boundary_cells`]); `None` for a recorded cloud.
    pub half_angles: Option<[f64; 2]>,
    /// The pixel raster a recorded cloud was measured on (a depth
    /// image's), where its beams' neighbours are for pooling (§5.5);
    /// `None`: the grids' rasters.
    pub pixels: Option<PixelRaster>,
}

/// Where a cloud's points lie on the pixel raster that measured them (a
/// depth image's): point k in slot `slots[k]` = row × columns + column,
/// no two in one slot.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PixelRaster {
    /// Pixels a row.
    pub columns: usize,
    /// Rows.
    pub rows: usize,
    /// Each point's slot, in the points' order.
    pub slots: Vec<u32>,
}

/// One angular grid of a [`BeamLayout`]: its frame, its bins, and which
/// beam lies in which bin.
#[derive(Clone, Debug)]
pub struct BeamGrid {
    /// The grid's axes in the camera frame (grid x the boresight, z the pole).
    pub camera_from_grid: Matrix3,
    /// Azimuth bins (the raster's columns).
    pub azimuth: Axis,
    /// Elevation bins (the raster's rows).
    pub elevation: Axis,
    /// The beams on this grid with the raster slot of each (row × columns +
    /// column); `None`: every beam of the layout, beam k in slot k (a
    /// scanner's raster, row by row).
    pub members: Option<Vec<GridMember>>,
}

/// A beam on a [`BeamGrid`] and its slot in the grid's raster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridMember {
    /// The beam's index in the scan.
    pub beam: usize,
    /// Its raster slot: row × columns + column.
    pub slot: usize,
}

impl BeamLayout {
    /// The layout of a raster scanner: `directions` row by row, one per
    /// (vertical, horizontal) angle pair of `raster`; one grid, one bin per
    /// beam.
    pub fn raster(directions: Vec<Vector3>, raster: Raster) -> Self {
        let (azimuth, elevation) = raster_axes(raster);
        let half_angle = |angles: &[f64]| angles.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        Self {
            directions,
            grids: vec![BeamGrid {
                camera_from_grid: CAMERA_FROM_GRID,
                azimuth,
                elevation,
                members: None,
            }],
            half_angles: Some([half_angle(raster.horizontal), half_angle(raster.vertical)]),
            pixels: None,
        }
    }
}

impl PixelRaster {
    /// Each point with its slot.
    pub fn members(&self) -> Vec<GridMember> {
        let slot = |(beam, &slot): (usize, &u32)| GridMember {
            beam,
            slot: slot as usize,
        };
        self.slots.iter().enumerate().map(slot).collect()
    }
}

impl BeamGrid {
    /// How many beams the grid bins.
    pub fn len(&self, layout: &BeamLayout) -> usize {
        self.members
            .as_ref()
            .map_or(layout.directions.len(), Vec::len)
    }

    /// The scan's index of the grid's `k`-th beam.
    #[inline]
    pub fn beam(&self, k: usize) -> usize {
        self.members.as_ref().map_or(k, |m| m[k].beam)
    }

    /// The raster slots: `(beam, slot)` of every beam on the grid.
    pub fn slots(&self, layout: &BeamLayout) -> Vec<GridMember> {
        match &self.members {
            Some(members) => members.clone(),
            None => (0..layout.directions.len())
                .map(|k| GridMember { beam: k, slot: k })
                .collect(),
        }
    }

    /// Bins: azimuth × elevation.
    pub fn bins(&self) -> f64 {
        self.azimuth.count as f64 * self.elevation.count as f64
    }

    /// The half-angles (rad) of its outermost azimuth and elevation bin
    /// edges from the grid's boresight: the pyramid its beams stay in.
    pub fn half_angles(&self) -> [f64; 2] {
        [&self.azimuth, &self.elevation].map(|axis| {
            let end = axis.start + axis.step * axis.count as f64;
            axis.start.abs().max(end.abs())
        })
    }
}

/// The beam layouts of a set of scans: one shared by every scan (a
/// scanner's raster) or one per scan (recorded clouds).
#[derive(Clone, Copy, Debug)]
pub enum Layouts<'a> {
    /// Every scan's beams lie as this one's.
    Shared(&'a BeamLayout),
    /// Scan i's beams lie as the i-th.
    PerScan(&'a [BeamLayout]),
}

impl<'a> Layouts<'a> {
    /// The layout of scan `i`.
    #[inline]
    pub fn of(&self, i: usize) -> &'a BeamLayout {
        match self {
            Layouts::Shared(layout) => layout,
            Layouts::PerScan(layouts) => &layouts[i],
        }
    }
}

/// What a mapper may know besides the scans: how their beams lie, the
/// range-error model it is calibrated with, how far beams reach, and the
/// map settings. Neither the scene nor any truth.
#[derive(Clone, Copy, Debug)]
pub struct MapperView<'a> {
    /// How each scan's beams lie.
    pub layouts: Layouts<'a>,
    /// The range noise model the maps are calibrated with (σ of each beam).
    pub range: RangeModel,
    /// How far a beam reaches (m): a no-return beam clears space up to it,
    /// and a hit beyond it is taken as one (OctoMap's maximum range).
    pub max_range: f64,
    /// How maps are built and fused.
    pub settings: &'a MapSettings,
    /// The sigma-point set of the `unscented` and `correlated` methods.
    pub sigma_set: SigmaSet,
}

/// Most finest cells the boundary of one viewpoint's cleared space may hold
/// ([`check_clearing`]): the uncertainty-aware merge evaluates each (about
/// a microsecond and tens of bytes apiece), so beyond this one map takes
/// minutes and gigabytes.
pub const MAX_CLEARED_BOUNDARY_CELLS: f64 = 1e8;

/// The finest cells of edge `resolution` on the boundary of the space one
/// viewpoint clears when none of its beams returns. The boundary is the
/// surface of the field of view's pyramid out to the maximum range R
/// (half-angles α, β of the outermost columns and rows), of area `A = R²
/// (4 tan α tan β + 2 tan α / cos β + 2 tan β / cos α)`; the cells whose
/// circumscribed ball (radius √3/2 of an edge) meets it fill a layer √3
/// edges thick: `√3 A / resolution²` cells. Inside, free space is updated
/// a whole node at a time; these cells one by one.
pub fn cleared_boundary_cells([alpha, beta]: [f64; 2], max_range: f64, resolution: f64) -> f64 {
    let area = max_range.powi(2)
        * (4.0 * alpha.tan() * beta.tan()
            + 2.0 * alpha.tan() / beta.cos()
            + 2.0 * beta.tan() / alpha.cos());
    3f64.sqrt() * area / (resolution * resolution)
}

/// Checks that a map of `resolution` can be built by the uncertainty-aware
/// methods from a raster of `half_angles` reaching `max_range`: at most
/// [`MAX_CLEARED_BOUNDARY_CELLS`] cells on the boundary of a viewpoint's
/// cleared space ([`cleared_boundary_cells`]).
pub fn check_clearing(
    half_angles: [f64; 2],
    max_range: f64,
    resolution: f64,
) -> Result<(), String> {
    let cells = cleared_boundary_cells(half_angles, max_range, resolution);
    if cells <= MAX_CLEARED_BOUNDARY_CELLS {
        return Ok(());
    }
    Err(format!(
        "[sensor] max_range = {} m at resolution {resolution} m: a viewpoint whose beams \
         all miss clears space bounded by {cells:.2e} cells, which the uncertainty-aware \
         methods evaluate one by one; sigmap handles at most \
         {MAX_CLEARED_BOUNDARY_CELLS:.0e} (lower max_range or use a coarser resolution)",
        metres(max_range)
    ))
}

/// Checks that the uncertainty-aware methods can map a recorded cloud's
/// `scan` laid out as `layout` at `resolution`: the space it clears reaches
/// its farthest hit, or `max_range` where a point beyond it is a beam that
/// returned nothing, and the boundary of each grid's pyramid out to there
/// ([`cleared_boundary_cells`]) holds at most [`MAX_CLEARED_BOUNDARY_CELLS`]
/// cells in all. A point far outside the scene (a corrupt value, a
/// reflection) would otherwise make one scan's merge take gigabytes.
pub fn check_cloud_clearing(
    layout: &BeamLayout,
    scan: &Scan,
    max_range: f64,
    resolution: f64,
) -> Result<(), String> {
    let reach = scan
        .measurements
        .iter()
        .filter_map(|m| match m.status {
            BeamStatus::Hit => Some(m.range),
            BeamStatus::NoReturn => Some(max_range),
            _ => None,
        })
        .fold(0.0, f64::max);
    let cells: f64 = layout
        .grids
        .iter()
        .map(|grid| cleared_boundary_cells(grid.half_angles(), reach, resolution))
        .sum();
    if cells <= MAX_CLEARED_BOUNDARY_CELLS {
        return Ok(());
    }
    Err(format!(
        "its beams reach {} m at resolution {resolution} m: the space they clear is \
         bounded by {cells:.2e} cells, which the uncertainty-aware methods evaluate one by one; \
         sigmap handles at most {MAX_CLEARED_BOUNDARY_CELLS:.0e} (give a --max-range beyond \
         which points are beams that returned nothing, or use a coarser resolution)",
        metres(reach)
    ))
}

/// Refuses surface samples between beams (`interpolate_beams`) for a
/// viewpoint of `beams` beams (or grid bins) when beams and samples together
/// would pass the per-viewpoint limit, before any grid is built.
pub fn check_sample_budget(beams: f64) -> Result<(), String> {
    use super::spherical::SAMPLES_PER_BEAM;
    let limit = MAX_BEAMS_PER_VIEWPOINT / (1 + SAMPLES_PER_BEAM) as f64;
    if beams > limit {
        return Err(format!(
            "interpolate_beams: {beams:.0} beams per viewpoint would make up to {:.0} surface \
             samples; with samples sigmap handles at most {limit:.0} beams per viewpoint (use \
             larger sensor steps, or set interpolate_beams = \"off\")",
            beams * SAMPLES_PER_BEAM as f64
        ));
    }
    Ok(())
}
