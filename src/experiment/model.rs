//! Building a map from a run's scans with one modelling method: what the
//! modeller can do with the scans alone. The truth cannot enter: map
//! building takes a [`MapperView`] (scanner geometry, range-error model, map
//! settings; no scene) and [`Scan`]s (measurements and the believed chain;
//! the simulator keeps the truth in types of its own, which this file never
//! names: tests/doc_refs.rs checks it).

use super::Experiment;
use crate::error::{Error, Result};
use crate::geometry::{Matrix3, Matrix6, Point3, Vector3};
use crate::mapping::merge::MergePlan;
use crate::mapping::pipeline::prepare_and_insert;
use crate::mapping::pooling::{pool_ranges, Pooled, PooledRange, Pooling};
use crate::mapping::ray_update::RayUpdater;
use crate::mapping::shared_motion::expect_over_shared_motion;
use crate::mapping::spherical::{BeamEnd, GridBuffers};
use crate::mapping::surface_cells::SurfaceCells;
use crate::mapping::viewpoint::{local_grid_of, nominal_bins, Raster};
use crate::mapping::{Clamp, MapSettings, Octree};
use crate::sim::scan::{BeamStatus, Measurement, Scan};
use crate::sim::sensor::RangeModel;
use crate::sim::sensor::Scanner;
use crate::uncertainty::{
    BlindPropagator, JacobianPropagator, Propagator, SigmaSet, UncertainChain, UncertainPoint,
    UnscentedPropagator,
};
use std::fmt;
use std::str::FromStr;
use std::sync::Mutex;

/// How a map is built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Method {
    /// OPDF merge, range covariance only (chain exact).
    Blind,
    /// OPDF merge, covariances by first-order propagation.
    Jacobian,
    /// OPDF merge, covariances by the unscented transform.
    Unscented,
    /// The unscented OPDF merge with the viewpoints fused on their own
    /// (arm) error only, and the shared errors (T_sw, T_cr, one draw per run)
    /// accounted once on the fused map (docs/math.md §6.6).
    Correlated,
    /// OctoMap's ray update (hit/miss log-odds), the baseline most users run.
    RayUpdate,
    /// Not a mapper: the true occupancy as the run's drawn scene registration
    /// (T_sw) places it, what a perfect sensor on a perfect arm would map.
    /// A scoring reference for `sigmap run` (`runner::registered_truth`): the
    /// ceiling for any map that cannot see the registration error.
    RegisteredTruth,
}

impl Method {
    /// Every method.
    pub const ALL: [Method; 6] = [
        Method::Blind,
        Method::Jacobian,
        Method::Unscented,
        Method::Correlated,
        Method::RayUpdate,
        Method::RegisteredTruth,
    ];

    /// Whether it builds local grids from propagated beams (the OPDF
    /// methods), not rays or the truth.
    pub fn builds_grids(self) -> bool {
        !matches!(self, Method::RayUpdate | Method::RegisteredTruth)
    }

    /// Its name in files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Blind => "blind",
            Method::Jacobian => "jacobian",
            Method::Unscented => "unscented",
            Method::Correlated => "correlated",
            Method::RayUpdate => "ray_update",
            Method::RegisteredTruth => "registered_truth",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| {
                format!(
                    "unknown method '{s}' (use blind, jacobian, unscented, correlated, ray_update \
                     or registered_truth)"
                )
            })
    }
}

/// Why scans cannot give `registered_truth`.
pub const REGISTERED_TRUTH_FROM_SCANS: &str =
    "registered_truth is a scoring reference built from a simulated run's truth, not from scans: \
     give an experiment (`sigmap map EXPERIMENT --method registered_truth`, or list it in the \
     experiment's `methods` for `sigmap run`)";

/// What a mapper may know of an experiment: the scanner's geometry, the
/// range-error model it is calibrated with, and the map settings. Neither
/// the scene nor any truth.
#[derive(Clone, Copy)]
pub struct MapperView<'a> {
    /// Beam directions, raster and range limits.
    pub scanner: &'a Scanner,
    /// The range noise model (σ as a function of range).
    pub range: &'a RangeModel,
    /// How maps are built and fused.
    pub settings: &'a MapSettings,
    /// The sigma-point set of the `unscented` and `correlated` methods.
    pub sigma_set: SigmaSet,
}

impl<'a> MapperView<'a> {
    /// The view of `experiment` a mapper gets.
    pub fn of(experiment: &'a Experiment) -> Self {
        Self {
            scanner: &experiment.scanner,
            range: &experiment.profile.range,
            settings: &experiment.map,
            sigma_set: experiment.sigma_set,
        }
    }
}

/// The propagator of an OPDF method for one viewpoint's chain: the
/// per-point marginal (for `correlated`, the full covariance, as its
/// consistency is checked), sigma-point methods with `sigma_set`; `None` for
/// the ray update, which propagates nothing.
pub fn propagator(
    method: Method,
    chain: &UncertainChain,
    sigma_set: SigmaSet,
) -> Option<Box<dyn Propagator>> {
    match method {
        Method::Blind => Some(Box::new(BlindPropagator::new(chain))),
        Method::Jacobian => Some(Box::new(JacobianPropagator::new(chain))),
        Method::Unscented | Method::Correlated => {
            Some(Box::new(UnscentedPropagator::new(chain, sigma_set)))
        }
        Method::RayUpdate | Method::RegisteredTruth => None,
    }
}

/// The links drawn once per run (scene registration, hand-eye): shared by
/// every viewpoint of a run (docs/math.md §6.6).
const SHARED_LINKS: [&str; 2] = ["world_from_scene", "robot_from_camera"];

/// `chain` with only the shared links uncertain (`shared`) or only the
/// others (`!shared`).
pub fn split_chain(chain: &UncertainChain, shared: bool) -> UncertainChain {
    let mut out = chain.clone();
    for link in &mut out.links {
        if SHARED_LINKS.contains(&link.name.as_str()) != shared {
            link.pose.covariance = Matrix6::zeros();
        }
    }
    out
}

/// The chain of a scan as the modeller believes it.
pub fn scan_chain(scan: &Scan) -> UncertainChain {
    UncertainChain::paper(
        scan.chain.world_from_scene,
        scan.chain.world_from_robot,
        scan.chain.robot_from_camera,
    )
}

/// One beam's propagated end, scene frame, from its measurement `m`,
/// camera-frame direction `d` and measured point: a hit with its
/// covariance, a no-return beam as its direction; a too-close or dropped
/// beam carries nothing.
fn beam_end(
    m: &Measurement,
    d: &Vector3,
    point: Option<&UncertainPoint>,
    propagator: &dyn Propagator,
    scene_from_camera: &Matrix3,
) -> Option<BeamEnd> {
    match (m.status, point) {
        (BeamStatus::Hit, Some(point)) => {
            let g = propagator.propagate(point);
            Some(BeamEnd::Hit {
                point: g.mean,
                covariance: g.covariance,
            })
        }
        (BeamStatus::NoReturn, _) => Some(BeamEnd::Miss {
            direction: scene_from_camera * d,
        }),
        _ => None,
    }
}

/// Beam `k` of `scan` as an OPDF map draws it (scene frame): its
/// [`surface_point`] from `points` (the scan's [`measured_ranges`]; `None`:
/// its raw range) propagated through the chain, or its direction if it
/// returned nothing.
fn map_beam_end(
    view: &MapperView,
    scan: &Scan,
    points: Option<&[Pooled]>,
    k: usize,
    propagator: &dyn Propagator,
    scene_from_camera: &Matrix3,
) -> Option<BeamEnd> {
    let (m, d) = (&scan.measurements[k], &view.scanner.directions[k]);
    let point = points.map_or_else(
        || raw_point(view.range, m, d),
        |points| points[k].as_ref().map(|p| surface_point(view.range, d, p)),
    );
    beam_end(m, d, point.as_ref(), propagator, scene_from_camera)
}

/// What a scan measured along each beam (`None`: no hit): the raw range
/// with the range model's σ, or with `beam_pooling` the range pooled on the
/// viewpoint's local plane or face (docs/math.md §5.5). The same for every
/// method: compute it once per scan. [`surface_point`] is what a map draws
/// from it, [`hit_point`] what the NEES checks.
pub fn measured_ranges(view: &MapperView, scan: &Scan) -> Vec<Pooled> {
    let hit = |m: &Measurement| (m.status == BeamStatus::Hit).then_some(m.range);
    let ranges: Vec<Option<f64>> = scan.measurements.iter().map(hit).collect();
    pooled_ranges(
        view.settings.beam_pooling,
        view.scanner.columns,
        &view.scanner.directions,
        &ranges,
        view.range,
    )
}

/// [`pool_ranges`] with the range model's noise: `ranges[k]` is beam k's
/// measured range (`None`: no hit) along the unit camera-frame
/// `directions[k]`, row by row with `columns` per row.
fn pooled_ranges(
    pooling: Pooling,
    columns: usize,
    directions: &[Vector3],
    ranges: &[Option<f64>],
    range: &RangeModel,
) -> Vec<Pooled> {
    pool_ranges(
        pooling,
        columns,
        directions,
        ranges,
        |r| range.sigma(r),
        range.angular_sigma,
    )
}

/// Where the surface crosses the nominal line of the beam along the unit
/// camera-frame `d` that measured `p`, with the covariance a map draws its
/// chord and free space from (docs/math.md §5.4, §5.5): σ along the beam is
/// the raw range's or the fitted plane's prediction σ, without the slide of
/// a turned beam along a slanted plane, which is where the beam hit and not
/// where the surface meets the line the map draws.
pub fn surface_point(range: &RangeModel, d: &Vector3, p: &PooledRange) -> UncertainPoint {
    camera_point(range, d, p.range, p.sigma)
}

/// Where the beam along `d` that measured `p` hit the surface, with its
/// covariance: a pooled range's holds the slide (docs/math.md §5.5). What
/// the run's NEES checks against the true hit.
pub fn hit_point(range: &RangeModel, d: &Vector3, p: &PooledRange) -> UncertainPoint {
    match p.covariance(d, range.angular_sigma) {
        Some(covariance) => UncertainPoint {
            mean: d * p.range,
            covariance,
        },
        None => surface_point(range, d, p),
    }
}

/// The measured points of one raster of beams as a map draws them,
/// pooled as `pooling` asks (docs/math.md §5.5; the raster as for
/// [`pooled_ranges`]): each hit's [`surface_point`].
pub fn pooled_surface_points(
    pooling: Pooling,
    columns: usize,
    directions: &[Vector3],
    ranges: &[Option<f64>],
    range: &RangeModel,
) -> Vec<Option<UncertainPoint>> {
    pooled_ranges(pooling, columns, directions, ranges, range)
        .iter()
        .zip(directions)
        .map(|(p, d)| p.as_ref().map(|p| surface_point(range, d, p)))
        .collect()
}

/// A hit's measured point from its raw range (see [`measured_ranges`]).
fn raw_point(range: &RangeModel, m: &Measurement, d: &Vector3) -> Option<UncertainPoint> {
    (m.status == BeamStatus::Hit).then(|| camera_point(range, d, m.range, range.sigma(m.range)))
}

/// The camera-frame point at range `r` along `d`, range noise `sigma`.
fn camera_point(range: &RangeModel, d: &Vector3, r: f64, sigma: f64) -> UncertainPoint {
    UncertainPoint {
        mean: d * r,
        covariance: range.point_covariance_with(d, r, sigma),
    }
}

/// Builds the map of a run's `scans` at `resolution` with `method`, in the
/// map frame `map = scene + offset` (zero: the scene frame; see
/// `Experiment::map_offset`). Fails only when the `correlated` method's
/// shared-motion step would not fit in memory at this resolution.
pub fn build_map(
    view: &MapperView,
    scans: &[Scan],
    method: Method,
    resolution: f64,
    offset: &Vector3,
) -> Result<Octree> {
    build_map_measured(view, scans, None, method, resolution, offset)
}

/// [`build_map`] from the scans' [`measured_ranges`] (one per scan; the ray
/// update's rays end at them only with `beam_pooling`, and otherwise at the
/// raw hits, as OctoMap's), when they are computed once for all methods of
/// a run; `None`: each beam's is computed as its grid is built (with
/// `beam_pooling`, each scan's, and dropped with its grid).
pub fn build_map_measured(
    view: &MapperView,
    scans: &[Scan],
    measured: Option<&[Vec<Pooled>]>,
    method: Method,
    resolution: f64,
    offset: &Vector3,
) -> Result<Octree> {
    if method == Method::RegisteredTruth {
        return Err(Error::Usage(REGISTERED_TRUTH_FROM_SCANS.into()));
    }
    if method.builds_grids() {
        view.scanner
            .check_clearing(resolution)
            .map_err(|e| Error::Usage(format!("method {method}: {e}")))?;
    }
    let mut tree = Octree::new(resolution);
    let max_range = view.scanner.max_range;
    // Scans prepared and not yet inserted: at most one more than threads.
    let window = rayon::current_num_threads() + 1;
    if method == Method::RayUpdate {
        // Each scan's cells are found (on the tree's geometry alone) while
        // earlier scans' are applied; updaters and their buffers are reused.
        let geometry = Octree::new(resolution);
        let pooling = view.settings.beam_pooling != Pooling::Off;
        let spare = Mutex::new(Vec::<(RayUpdater, Vec<Point3>, Vec<Vector3>)>::new());
        let find = |i: usize| {
            let scan = &scans[i];
            let (mut updater, mut hits, mut misses) = spare
                .lock()
                .ok()
                .and_then(|mut s| s.pop())
                .unwrap_or_else(|| {
                    (
                        RayUpdater::new(view.settings.update),
                        Vec::new(),
                        Vec::new(),
                    )
                });
            // With beam pooling the rays end at the pooled points (the
            // run's, when it computed them for every method).
            let shared = measured.filter(|_| pooling).map(|m| &m[i][..]);
            let own = shared
                .is_none()
                .then(|| pooled_ray_ends(view, scan))
                .flatten();
            let points = shared.or(own.as_deref());
            let origin = ray_inputs_into(view, scan, points, &mut hits, &mut misses) + offset;
            hits.iter_mut().for_each(|h| *h += offset);
            // Every thread prepares its own scan; the last, with nothing
            // beside it, is spread over the pool.
            updater.walk_alone(i + 1 < scans.len());
            updater.find_cells(&geometry, &origin, &hits, &misses, max_range);
            (updater, hits, misses)
        };
        prepare_and_insert(scans.len(), window, find, |(updater, hits, misses)| {
            updater.apply(&mut tree);
            if let Ok(mut spare) = spare.lock() {
                spare.push((updater, hits, misses));
            }
        });
        tree.shrink_to_fit();
        return Ok(tree);
    }
    let raster = Raster {
        horizontal: &view.scanner.horizontal_angles,
        vertical: &view.scanner.vertical_angles,
    };
    let options = view.settings.merge_options();
    let geometry = Octree::new(resolution);
    // The scanner's nominal directions' bins, once for every scan.
    let nominal = nominal_bins(raster, &view.scanner.directions);
    // Scan i's local grid (its beams propagated and binned) and the cells
    // its surface bands reach.
    let grid_of = |i: usize, buffers: GridBuffers| {
        let scan = &scans[i];
        let full_chain = scan_chain(scan);
        let chain = if method == Method::Correlated {
            split_chain(&full_chain, false)
        } else {
            full_chain
        };
        let propagator =
            propagator(method, &chain, view.sigma_set).expect("an OPDF method has a propagator");
        let origin = propagator.origin();
        // Each beam's end is computed as it is binned: without pooling its
        // measured point too, so neither is ever held for the whole scan.
        let pooled = (measured.is_none() && view.settings.beam_pooling != Pooling::Off)
            .then(|| measured_ranges(view, scan));
        let points = measured.map(|m| &m[i]).or(pooled.as_ref());
        let scene_from_camera = chain.nominal().rotation.to_rotation_matrix().into_inner();
        let end = |k: usize| {
            let mut end = map_beam_end(
                view,
                scan,
                points.map(|p| &p[..]),
                k,
                propagator.as_ref(),
                &scene_from_camera,
            )?;
            if let BeamEnd::Hit { point, .. } = &mut end {
                *point += offset;
            }
            Some(end)
        };
        let mut grid = local_grid_of(
            buffers,
            (&(origin.mean + offset), &origin.covariance),
            &scene_from_camera,
            (raster, Some(&nominal)),
            (scan.measurements.len(), end),
            max_range,
        );
        if view.settings.interpolate_beams {
            grid.add_surface_samples();
        }
        grid
    };
    // Each scan's grid is built and searched (on the tree's geometry alone)
    // while earlier scans' changes are applied; the grids' and the plans'
    // memory is reused from scan to scan.
    let spare_grids = Mutex::new(Vec::<GridBuffers>::new());
    let spare_plans = Mutex::new(Vec::<MergePlan>::new());
    let search = |i: usize| {
        let buffers = spare_grids.lock().ok().and_then(|mut s| s.pop());
        let grid = grid_of(i, buffers.unwrap_or_default());
        let surfaces = SurfaceCells::new(&grid, &options.model, &geometry);
        let mut plan = spare_plans
            .lock()
            .ok()
            .and_then(|mut s| s.pop())
            .unwrap_or_default();
        plan.search(&geometry, &grid, &surfaces, &options);
        if let Ok(mut spare) = spare_grids.lock() {
            spare.push(grid.into_buffers());
        }
        plan
    };
    prepare_and_insert(scans.len(), window, search, |plan| {
        plan.apply(&mut tree, options.clamp);
        if let Ok(mut spare) = spare_plans.lock() {
            spare.push(plan);
        }
    });
    finish_opdf(tree, scans, method, offset, options.clamp)
}

/// The OPDF map's last steps once every grid is merged: the `correlated`
/// method's shared motion, then the tree's spare capacity released.
fn finish_opdf(
    mut tree: Octree,
    scans: &[Scan],
    method: Method,
    offset: &Vector3,
    clamp: Clamp,
) -> Result<Octree> {
    if method == Method::Correlated {
        let chains: Vec<_> = scans.iter().map(scan_chain).collect();
        take_shared_motion(&mut tree, &chains, offset, clamp)?;
    }
    tree.shrink_to_fit();
    Ok(tree)
}

/// The `correlated` method's last step: the shared pose errors of the
/// viewpoints' believed `chains`, taken once on the fused map (docs/math.md
/// §6.6). Fails only when it would not fit in memory at this resolution.
pub(crate) fn take_shared_motion(
    tree: &mut Octree,
    chains: &[UncertainChain],
    offset: &Vector3,
    clamp: Clamp,
) -> Result<()> {
    let shared: Vec<_> = chains
        .iter()
        .map(|chain| split_chain(chain, true))
        .collect();
    let covariance_at = shared_covariance(&shared, offset);
    expect_over_shared_motion(tree, &covariance_at, clamp)
        .map(|_| ())
        .map_err(|e| Error::Usage(format!("method correlated: {e}")))
}

/// `Σ(x)`: the covariance of the displacement of map point `x` by the
/// shared pose errors, the mean over the viewpoints' `shared` chains (each
/// with only its shared links uncertain, [`split_chain`]) of
/// `J_shared Γ_shared J_sharedᵀ` (first order; docs/math.md §6.6).
fn shared_covariance(
    shared: &[UncertainChain],
    offset: &Vector3,
) -> impl Fn(&Point3) -> Matrix3 + Sync {
    let views: Vec<_> = shared
        .iter()
        .map(|chain| {
            let camera_from_scene = chain.nominal().inverse();
            (camera_from_scene, JacobianPropagator::new(chain))
        })
        .collect();
    let offset = *offset;
    move |x: &Point3| {
        let scene = x - offset;
        let sum = views
            .iter()
            .map(|(camera_from_scene, p)| {
                p.propagate(&UncertainPoint {
                    mean: (camera_from_scene * scene).coords,
                    covariance: Matrix3::zeros(),
                })
                .covariance
            })
            .fold(Matrix3::zeros(), |a, b| a + b);
        sum / views.len().max(1) as f64
    }
}

/// The nominal origin, measured end points and no-return directions of a
/// scan, in the scene frame (what OctoMap's `insertPointCloud` is given).
pub fn ray_inputs(view: &MapperView, scan: &Scan) -> (Point3, Vec<Point3>, Vec<Vector3>) {
    let (mut hits, mut misses) = (Vec::new(), Vec::new());
    let origin = ray_inputs_into(view, scan, None, &mut hits, &mut misses);
    (origin, hits, misses)
}

/// Where a scan's rays end for the ray update: with beam pooling, at its
/// pooled [`measured_ranges`]; `None` without pooling (the raw hits, as
/// OctoMap's).
pub fn pooled_ray_ends(view: &MapperView, scan: &Scan) -> Option<Vec<Pooled>> {
    (view.settings.beam_pooling != Pooling::Off).then(|| measured_ranges(view, scan))
}

/// [`ray_inputs`] into buffers of the caller's (reused from scan to scan:
/// fresh ones cost a page fault every 4 KiB); with `points` (the scan's
/// [`measured_ranges`], pooled), each hit ends at its measured range.
pub fn ray_inputs_into(
    view: &MapperView,
    scan: &Scan,
    points: Option<&[Pooled]>,
    hits: &mut Vec<Point3>,
    misses: &mut Vec<Vector3>,
) -> Point3 {
    let pose = scan.chain.scene_from_camera();
    hits.clear();
    misses.clear();
    for (k, (m, d)) in scan
        .measurements
        .iter()
        .zip(&view.scanner.directions)
        .enumerate()
    {
        match m.status {
            BeamStatus::Hit => {
                let local = points
                    .and_then(|points| points[k].as_ref())
                    .map_or_else(|| d * m.range, |p| d * p.range);
                hits.push(pose * Point3::from(local));
            }
            BeamStatus::NoReturn => misses.push(pose.rotation * d),
            _ => {}
        }
    }
    Point3::from(pose.translation.vector)
}

#[cfg(test)]
mod tests;
