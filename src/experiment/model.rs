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
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use crate::mapping::octree::{Key, DEPTH};
    use crate::uncertainty::UncertainPose;
    use std::path::Path;

    fn quickstart() -> Experiment {
        Experiment::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/experiments/quickstart.toml"
        )))
        .unwrap()
    }

    #[test]
    fn the_chain_splits_into_shared_and_per_viewpoint_links() {
        let pose = |s: f64| {
            UncertainPose::from_sigmas(Pose::new([0.1, 0.2, 0.3], [0.1, 0.2, 0.3]), [s; 6])
        };
        let chain = UncertainChain::paper(pose(0.01), pose(0.02), pose(0.03));
        let shared = split_chain(&chain, true);
        let own = split_chain(&chain, false);
        for i in 0..3 {
            assert_eq!(
                shared.links[i].pose.covariance + own.links[i].pose.covariance,
                chain.links[i].pose.covariance
            );
            assert_eq!(shared.links[i].pose.mean, chain.links[i].pose.mean);
        }
        // T_sw and T_cr are shared; T_rw is the viewpoint's own.
        assert!(shared.links[0].pose.covariance[(0, 0)] > 0.0);
        assert!(shared.links[1].pose.is_exact());
        assert!(shared.links[2].pose.covariance[(0, 0)] > 0.0);
        assert!(own.links[1].pose.covariance[(0, 0)] > 0.0);
    }

    #[test]
    fn a_whole_cell_offset_shifts_the_map_by_that_cell() {
        // The map frame is `scene + offset` for origins and hits alike: a
        // whole-cell offset moves every cell's value to the cell that many
        // keys away, up to the rounding of a point near a cell face.
        let experiment = quickstart();
        let run = super::super::simulate(&experiment, 1, |_| {}).unwrap();
        let view = MapperView::of(&experiment);
        let resolution = 0.02;
        let shift = [3i32, -2, 1];
        let offset = Vector3::from(shift.map(|s| f64::from(s) * resolution));
        for method in [Method::Unscented, Method::RayUpdate] {
            let map = |offset: &Vector3| {
                build_map(&view, &run.scans, method, resolution, offset).unwrap()
            };
            let (still, moved) = (map(&Vector3::zeros()), map(&offset));
            let leaves = still.leaves();
            let differ = leaves
                .iter()
                .filter(|leaf| {
                    let key = Key(std::array::from_fn(|a| {
                        (i32::from(leaf.key.0[a]) + shift[a]) as u16
                    }));
                    let there = moved.query(&key, DEPTH);
                    there.is_none_or(|v| (v - leaf.value).abs() > 0.05)
                })
                .count();
            assert!(
                differ * 500 < leaves.len(),
                "{method}: {differ} of {} leaves moved elsewhere",
                leaves.len()
            );
        }
    }

    #[test]
    fn a_map_is_the_same_file_whatever_the_thread_count() {
        // Scans are prepared on every thread and applied in order
        // (mapping::pipeline): one, two and three threads, the same bytes.
        let experiment = quickstart();
        let run = super::super::simulate(&experiment, 1, |_| {}).unwrap();
        let view = MapperView::of(&experiment);
        let clamp = view.settings.update.clamp;
        for method in [Method::Unscented, Method::Correlated, Method::RayUpdate] {
            let file = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let tree = pool.install(|| {
                    build_map(&view, &run.scans, method, 0.05, &Vector3::zeros()).unwrap()
                });
                crate::mapping::octomap_io::to_bt(&tree, clamp)
            };
            let one = file(1);
            assert!(one.len() > 1000, "{method}: {} bytes", one.len());
            for threads in [2, 3] {
                assert!(file(threads) == one, "{method}: {threads} threads");
            }
        }
    }

    #[test]
    fn without_shared_error_the_correlated_map_is_the_unscented_map() {
        let mut experiment = quickstart();
        let offset = Vector3::zeros();
        let maps = |experiment: &Experiment| {
            let run = super::super::simulate(experiment, 1, |_| {}).unwrap();
            let view = MapperView::of(experiment);
            let map = |m| build_map(&view, &run.scans, m, 0.02, &offset).unwrap();
            (map(Method::Unscented), map(Method::Correlated))
        };
        let (unscented, correlated) = maps(&experiment);
        assert_ne!(
            unscented, correlated,
            "the shared error is accounted differently"
        );
        experiment.profile.world_from_scene = Matrix6::zeros();
        experiment.profile.robot_from_camera = Matrix6::zeros();
        let (unscented, correlated) = maps(&experiment);
        assert_eq!(unscented, correlated);
    }

    #[test]
    fn the_shared_error_is_taken_once_on_the_fused_map() {
        // The same scans, believed with and without shared covariance: the
        // viewpoints fuse identically (arm error only), so the maps differ
        // only by the shared-motion step, which must have run.
        let experiment = quickstart();
        let run = super::super::simulate(&experiment, 1, |_| {}).unwrap();
        let mut believed_exact = run.scans.clone();
        for scan in &mut believed_exact {
            scan.chain.world_from_scene.covariance = Matrix6::zeros();
            scan.chain.robot_from_camera.covariance = Matrix6::zeros();
        }
        let offset = Vector3::zeros();
        let view = MapperView::of(&experiment);
        let map =
            |scans: &[Scan]| build_map(&view, scans, Method::Correlated, 0.02, &offset).unwrap();
        let (with_shared, without) = (map(&run.scans), map(&believed_exact));
        assert_ne!(with_shared, without, "the shared-motion step ran");
    }

    #[test]
    fn pooling_narrows_most_hits_and_only_when_asked() {
        let mut experiment = quickstart();
        let run = super::super::simulate(&experiment, 1, |_| {}).unwrap();
        let scan = &run.scans[0];
        let along = |e: &Experiment| -> Vec<(f64, f64)> {
            let view = MapperView::of(e);
            measured_ranges(&view, scan)
                .iter()
                .zip(&e.scanner.directions)
                .filter_map(|(p, d)| {
                    let p = surface_point(view.range, d, p.as_ref()?);
                    Some((
                        p.mean.norm(),
                        (d.transpose() * p.covariance * d)[(0, 0)].sqrt(),
                    ))
                })
                .collect()
        };
        let sigma = |r: f64| experiment.profile.range.sigma(r);
        let raw = along(&experiment);
        assert!(raw.iter().all(|(r, s)| (s - sigma(*r)).abs() < 1e-12));
        experiment.map.beam_pooling = Pooling::Windows;
        let pooled = along(&experiment);
        assert_eq!(pooled.len(), raw.len());
        let narrowed = pooled.iter().filter(|(r, s)| *s < 0.6 * sigma(*r)).count();
        assert!(
            narrowed * 2 > pooled.len(),
            "{narrowed} of {} hits pooled",
            pooled.len()
        );
    }

    #[test]
    fn maps_draw_pooled_beams_without_the_slide_and_the_nees_keeps_it() {
        // With the chain exact (blind), a beam's σ along its scene-frame
        // line is the σ of the camera-frame point the map drew: the pooled
        // range's own (the plane's prediction), not the hit's, which adds
        // the slide r σ_a tan θ on a slanted plane.
        let mut experiment = quickstart();
        experiment.map.beam_pooling = Pooling::Windows;
        let run = super::super::simulate(&experiment, 1, |_| {}).unwrap();
        let view = MapperView::of(&experiment);
        let scan = &run.scans[0];
        let measured = measured_ranges(&view, scan);
        let chain = scan_chain(scan);
        let propagator = propagator(Method::Blind, &chain, view.sigma_set).unwrap();
        let origin = propagator.origin().mean;
        let scene_from_camera = chain.nominal().rotation.to_rotation_matrix().into_inner();
        let (mut pooled, mut slanted) = (0, 0);
        for (k, (p, d)) in measured.iter().zip(&view.scanner.directions).enumerate() {
            let Some(p) = p else { continue };
            let end = map_beam_end(
                &view,
                scan,
                Some(&measured),
                k,
                propagator.as_ref(),
                &scene_from_camera,
            );
            let Some(BeamEnd::Hit { point, covariance }) = end else {
                panic!("beam {k} measured a range and is not a hit");
            };
            let v = (point - origin).normalize();
            let drawn = (v.transpose() * covariance * v)[(0, 0)].sqrt();
            assert!(
                (drawn - p.sigma).abs() <= 1e-9 * p.sigma,
                "beam {k}: σ {drawn} drawn, {} measured",
                p.sigma
            );
            let hit = hit_point(view.range, d, p);
            let hit_sigma = (d.transpose() * hit.covariance * d)[(0, 0)].sqrt();
            assert!(hit_sigma >= p.sigma * (1.0 - 1e-12));
            pooled += usize::from(p.normal.is_some());
            slanted += usize::from(hit_sigma > 1.1 * p.sigma);
        }
        assert!(pooled > 1000, "{pooled} pooled beams");
        assert!(slanted * 10 > pooled, "{slanted} of {pooled} with a slide");
    }

    #[test]
    fn the_ray_update_ends_its_rays_at_the_pooled_points() {
        let mut experiment = quickstart();
        let run = super::super::simulate(&experiment, 1, |_| {}).unwrap();
        let resolution = 0.02;
        let ray_map = |e: &Experiment| {
            build_map(
                &MapperView::of(e),
                &run.scans,
                Method::RayUpdate,
                resolution,
                &Vector3::zeros(),
            )
            .unwrap()
            .leaves()
        };
        let raw = ray_map(&experiment);
        experiment.map.beam_pooling = Pooling::Faces;
        let view = MapperView::of(&experiment);
        // OctoMap's update, scan by scan, of rays ending at the pooled points.
        let mut expected = Octree::new(resolution);
        for scan in &run.scans {
            let points = measured_ranges(&view, scan);
            let pose = scan.chain.scene_from_camera();
            let (mut hits, mut misses) = (Vec::new(), Vec::new());
            for ((m, d), p) in scan
                .measurements
                .iter()
                .zip(&view.scanner.directions)
                .zip(&points)
            {
                match m.status {
                    BeamStatus::Hit => hits.push(pose * Point3::from(d * p.unwrap().range)),
                    BeamStatus::NoReturn => misses.push(pose.rotation * d),
                    _ => {}
                }
            }
            let origin = Point3::from(pose.translation.vector);
            RayUpdater::new(view.settings.update).insert_scan(
                &mut expected,
                &origin,
                &hits,
                &misses,
                view.scanner.max_range,
            );
        }
        let pooled = ray_map(&experiment);
        assert!(
            pooled == expected.leaves(),
            "the ray update ignored the pooled points"
        );
        assert!(pooled != raw);
        // The same when the run hands every method the scans' points.
        let measured: Vec<_> = run
            .scans
            .iter()
            .map(|s| measured_ranges(&view, s))
            .collect();
        let shared = build_map_measured(
            &view,
            &run.scans,
            Some(&measured),
            Method::RayUpdate,
            resolution,
            &Vector3::zeros(),
        )
        .unwrap();
        assert!(shared.leaves() == pooled);
    }

    #[test]
    fn the_experiments_sigma_set_reaches_the_maps() {
        let mut experiment = quickstart();
        let run = super::super::simulate(&experiment, 1, |_| {}).unwrap();
        let map = |e: &Experiment, method| {
            let tree = build_map(
                &MapperView::of(e),
                &run.scans,
                method,
                0.02,
                &Vector3::zeros(),
            );
            crate::mapping::octomap_io::to_ot(&tree.unwrap())
        };
        let paper = map(&experiment, Method::Unscented);
        let blind = map(&experiment, Method::Blind);
        // α = 1, β = κ = 0 is the paper's set: λ = 0, the same spread √n
        // and weights 1/2n, a centre point of weight 0.
        experiment.sigma_set = SigmaSet::Scaled {
            alpha: 1.0,
            beta: 0.0,
            kappa: 0.0,
        };
        assert!(map(&experiment, Method::Unscented) == paper);
        // A narrower set with β = 2 weighs the centre point: another map,
        // and only for the sigma-point methods.
        experiment.sigma_set = SigmaSet::Scaled {
            alpha: 0.5,
            beta: 2.0,
            kappa: 0.0,
        };
        assert!(map(&experiment, Method::Unscented) != paper);
        assert!(map(&experiment, Method::Blind) == blind);
    }
}
