//! Building a map from scans with one method: the one map builder, for a
//! simulated run's scans and for recorded ones alike. It takes a
//! [`MapperView`] (beam layouts, range-error model, map settings; no scene)
//! and [`Scan`]s (measurements and the believed chain), so the truth cannot
//! enter (tests/doc_refs.rs checks that this file never names it).

use super::measured::{
    measured_ranges, pooled_ray_ends, raw_point, ray_inputs_into, surface_point,
};
use super::merge::MergePlan;
use super::method::{propagator, scan_chain, split_chain, truth_from_scans, Method};
use super::pipeline::prepare_and_insert;
use super::pooling::{Pooled, Pooling};
use super::ray_update::{DiscreteScan, RayUpdater};
use super::scan::{
    check_clearing, check_cloud_clearing, check_sample_budget, BeamGrid, BeamLayout, BeamStatus,
    Layouts, MapperView, Scan,
};
use super::shared_motion::expect_over_shared_motion;
use super::spherical::{BeamEnd, GridBuffers, GridLayout, LocalGrid, NominalBins};
use super::surface_cells::SurfaceCells;
use super::{Clamp, Octree};
use crate::error::{Error, Result};
use crate::geometry::{Matrix3, Point3, Vector3};
use crate::uncertainty::{
    Gaussian3, JacobianPropagator, Propagator, UncertainChain, UncertainPoint,
};
pub use phases::{Phase, PhaseTimes};
use std::sync::Mutex;

/// What a map build may be given besides the scans.
#[derive(Clone, Copy, Default)]
pub struct BuildExtras<'a> {
    /// The scans' [`measured_ranges`] (one per scan), when they are computed
    /// once for all methods of a run; `None`: each scan's is computed as its
    /// grid is built. The ray update's rays end at them only when it pools
    /// as the other methods do (`MapSettings::ray_pooling`), and otherwise
    /// at its own pooled ranges or the raw hits, as OctoMap's.
    pub measured: Option<&'a [Vec<Pooled>]>,
    /// Called with `k` once the first `k` scans are in the map.
    pub done: Option<&'a (dyn Fn(usize) + Sync)>,
    /// The most bytes the map's node pools may take ([`Octree::pool_bytes`],
    /// checked after each scan); `None`: [`MAX_MAP_BYTES`].
    pub max_bytes: Option<usize>,
    /// Where a map's time goes, summed here step by step ([`Phase`]).
    pub phases: Option<&'a PhaseTimes>,
}

/// The most memory a map may take while it is built: 6 GiB. A map that
/// outgrows it stops with a one-line error after the scan that passed it
/// (a finer resolution or a longer `max_range` than the scans support),
/// before the machine runs out of memory.
pub const MAX_MAP_BYTES: usize = 6 << 30;

/// The error of a map that outgrew `limit` bytes after scan `scan` (1-based)
/// of `scans`.
fn outgrown(tree: &Octree, limit: usize, scan: usize, scans: usize) -> String {
    format!(
        "the map outgrew {:.2} GB after scan {scan} of {scans} at resolution {} m (sigmap builds \
         maps of at most {:.2} GB; use a coarser resolution or a shorter max_range)",
        tree.pool_bytes() as f64 / 1e9,
        tree.resolution(),
        limit as f64 / 1e9
    )
}

/// Builds the map of `scans` at `resolution` with `method`, in the map
/// frame `map = scene + offset` (zero: the scene frame). Fails on inputs
/// the method cannot map (beam pooling over an irregular raster, a grid past
/// the sample budget), or when the `correlated` method's shared-motion step
/// would not fit in memory at this resolution.
pub fn build_map(
    view: &MapperView,
    scans: &[Scan],
    method: Method,
    resolution: f64,
    offset: &Vector3,
) -> Result<Octree> {
    build_map_with(
        view,
        scans,
        BuildExtras::default(),
        method,
        resolution,
        offset,
    )
}

/// [`build_map`] with the [`BuildExtras`].
pub fn build_map_with(
    view: &MapperView,
    scans: &[Scan],
    extras: BuildExtras,
    method: Method,
    resolution: f64,
    offset: &Vector3,
) -> Result<Octree> {
    check_method(view, scans, method, resolution)?;
    let tree = if method.casts_rays() {
        let discrete = method == Method::RayUpdateDiscrete;
        ray_update_map(view, scans, extras, (resolution, discrete), offset)?
    } else {
        let tree = opdf_map(view, scans, extras, method, resolution, offset)?;
        finish_opdf(
            tree,
            scans,
            method,
            offset,
            view.settings.merge_options().clamp,
        )?
    };
    Ok(tree)
}

/// Refuses what `method` cannot build from scans laid out as `view` says,
/// before anything is built.
fn check_method(view: &MapperView, scans: &[Scan], method: Method, resolution: f64) -> Result<()> {
    if method.is_truth() {
        return Err(Error::Usage(truth_from_scans(method)));
    }
    if !method.builds_grids() {
        return Ok(());
    }
    let layouts: &[BeamLayout] = match view.layouts {
        Layouts::Shared(layout) => std::slice::from_ref(layout),
        Layouts::PerScan(layouts) => &layouts[..scans.len().min(layouts.len())],
    };
    for (i, layout) in layouts.iter().enumerate() {
        view.range
            .check_directions(&layout.directions)
            .map_err(|e| match view.layouts {
                Layouts::Shared(_) => format!("method {method}, the sensor's beams: {e}"),
                Layouts::PerScan(_) => format!("method {method}, scan {i}: {e}"),
            })
            .map_err(Error::Usage)?;
        match layout.half_angles {
            Some(half_angles) => check_clearing(half_angles, view.max_range, resolution)
                .map_err(|e| Error::Usage(format!("method {method}: {e}")))?,
            // A recorded cloud (one layout per scan): its own reach.
            None => check_cloud_clearing(layout, &scans[i], view.max_range, resolution)
                .map_err(|e| Error::Usage(format!("method {method}, scan {i}: {e}")))?,
        }
        if view.settings.interpolate_beams {
            for grid in &layout.grids {
                check_sample_budget(grid.bins()).map_err(Error::Usage)?;
            }
        }
    }
    Ok(())
}

/// Scans prepared and not yet inserted: at most one more than threads.
fn window() -> usize {
    rayon::current_num_threads() + 1
}

/// One scan of the ray update in the making, and its buffers for the next:
/// the rays' ends (hits and no-return directions) and, for the discretized
/// insertion, the end cells' centres.
struct RayScan {
    updater: RayUpdater,
    hits: Vec<Point3>,
    misses: Vec<Vector3>,
    discrete: DiscreteScan,
}

impl RayScan {
    fn new(rule: super::ray_update::UpdateRule) -> Self {
        Self {
            updater: RayUpdater::new(rule),
            hits: Vec::new(),
            misses: Vec::new(),
            discrete: DiscreteScan::default(),
        }
    }
}

/// OctoMap's ray update of every scan: each scan's cells are found (on the
/// tree's geometry alone) while earlier scans' are applied; updaters and
/// their buffers are reused. `discretized`: OctoMap's discretized
/// insertion ([`DiscreteScan`]).
fn ray_update_map(
    view: &MapperView,
    scans: &[Scan],
    extras: BuildExtras,
    (resolution, discretized): (f64, bool),
    offset: &Vector3,
) -> Result<Octree> {
    let mut tree = Octree::new(resolution);
    let geometry = Octree::new(resolution);
    let settings = view.settings;
    let pooling =
        settings.ray_pooling != Pooling::Off && settings.ray_pooling == settings.beam_pooling;
    let spare = Mutex::new(Vec::<RayScan>::new());
    let find = |i: usize| -> std::result::Result<RayScan, String> {
        let (scan, layout) = (&scans[i], view.layouts.of(i));
        let RayScan {
            mut updater,
            mut hits,
            mut misses,
            mut discrete,
        } = pop(&spare).unwrap_or_else(|| RayScan::new(view.settings.update));
        // With beam pooling the rays end at the pooled points (the run's,
        // when it computed them for every method and pools as they do).
        let shared = extras.measured.filter(|_| pooling).map(|m| &m[i][..]);
        let own = match shared {
            Some(_) => None,
            None => pooled_ray_ends(view, layout, scan)?,
        };
        let points = shared.or(own.as_deref());
        let origin = ray_inputs_into(layout, scan, points, &mut hits, &mut misses) + offset;
        hits.iter_mut().for_each(|h| *h += offset);
        // Every thread prepares its own scan; the last, with nothing beside
        // it, is spread over the pool.
        updater.walk_alone(i + 1 < scans.len());
        timed(extras.phases, Phase::RayWalk, || {
            if discretized {
                let ends = (&hits[..], &misses[..]);
                let centres = discrete.fill(&geometry, &origin, ends, view.max_range);
                updater.find_cells(&geometry, &origin, centres, &[], view.max_range);
            } else {
                updater.find_cells(&geometry, &origin, &hits, &misses, view.max_range);
            }
        });
        Ok(RayScan {
            updater,
            hits,
            misses,
            discrete,
        })
    };
    insert_scans(&mut tree, scans.len(), &extras, find, |tree, found| {
        timed(extras.phases, Phase::TreeUpdate, || {
            found.updater.apply(tree);
        });
        if let Ok(mut spare) = spare.lock() {
            spare.push(found);
        }
    })?;
    tree.shrink_to_fit();
    Ok(tree)
}

/// One scan as an OPDF method draws it: its propagator, its origin and
/// rotation, and its measured ranges when pooled here.
struct PreparedScan<'a> {
    scan: &'a Scan,
    layout: &'a BeamLayout,
    propagator: Box<dyn Propagator>,
    origin: Gaussian3,
    scene_from_camera: Matrix3,
    pooled: Option<Vec<Pooled>>,
}

impl<'a> PreparedScan<'a> {
    fn new(
        view: &MapperView<'a>,
        scans: &'a [Scan],
        i: usize,
        extras: BuildExtras,
        method: Method,
    ) -> std::result::Result<Self, String> {
        let (scan, layout) = (&scans[i], view.layouts.of(i));
        let full_chain = scan_chain(scan);
        let chain = if method == Method::Correlated {
            split_chain(&full_chain, false)
        } else {
            full_chain
        };
        let propagator =
            propagator(method, &chain, view.sigma_set).expect("an OPDF method has a propagator");
        let origin = propagator.origin();
        // Without pooling each beam's measured point is computed as it is
        // binned, so neither is ever held for the whole scan.
        let pooled = if extras.measured.is_none() && view.settings.beam_pooling != Pooling::Off {
            Some(measured_ranges(view, layout, scan)?)
        } else {
            None
        };
        let scene_from_camera = chain.nominal().rotation.to_rotation_matrix().into_inner();
        Ok(Self {
            scan,
            layout,
            propagator,
            origin,
            scene_from_camera,
            pooled,
        })
    }

    /// Beam `k`'s propagated end in the map frame: its surface point (from
    /// the pooled `points`, else its raw range) propagated through the
    /// chain, or its direction if it returned nothing; a too-close or
    /// dropped beam carries nothing.
    fn beam_end(
        &self,
        view: &MapperView,
        points: Option<&[Pooled]>,
        k: usize,
        offset: &Vector3,
    ) -> Option<BeamEnd> {
        let (m, d) = (&self.scan.measurements[k], &self.layout.directions[k]);
        match m.status {
            BeamStatus::Hit => {
                let point = match points {
                    Some(points) => points[k].as_ref().map(|p| surface_point(&view.range, d, p)),
                    None => raw_point(view, m, d),
                }?;
                let g = self.propagator.propagate(&point);
                Some(BeamEnd::Hit {
                    point: g.mean + offset,
                    covariance: g.covariance,
                })
            }
            BeamStatus::NoReturn => Some(BeamEnd::Miss {
                direction: self.scene_from_camera * d,
            }),
            _ => None,
        }
    }

    /// The local grid of `grid`'s beams, in the memory of `buffers`.
    fn local_grid(
        &self,
        view: &MapperView,
        extras: BuildExtras,
        i: usize,
        grid: &BeamGrid,
        (nominal, buffers): (Option<&NominalBins<'_>>, GridBuffers),
        offset: &Vector3,
    ) -> LocalGrid {
        let points = extras
            .measured
            .map(|m| &m[i][..])
            .or(self.pooled.as_deref());
        let layout = GridLayout {
            origin: self.origin.mean + offset,
            scene_from_grid: self.scene_from_camera * grid.camera_from_grid,
            azimuth: grid.azimuth,
            elevation: grid.elevation,
            max_range: view.max_range,
        };
        let end = |k: usize| self.beam_end(view, points, grid.beam(k), offset);
        let count = grid.len(self.layout);
        let mut local = LocalGrid::from_ends_in(
            buffers,
            layout,
            nominal,
            (count, end),
            &self.origin.covariance,
        );
        if view.settings.interpolate_beams {
            local.add_surface_samples(
                &view.settings.sample_gate,
                (&view.range, &grid.camera_from_grid),
            );
        }
        local
    }
}

/// The bins of a shared raster's nominal directions, computed once per map:
/// they answer most beams' bin lookups in every viewpoint's grid.
fn shared_nominal_bins<'a>(view: &MapperView<'a>) -> Option<NominalBins<'a>> {
    let Layouts::Shared(layout) = view.layouts else {
        return None;
    };
    let [grid] = &layout.grids[..] else {
        return None;
    };
    grid.members.is_none().then(|| {
        NominalBins::new(
            &layout.directions,
            grid.camera_from_grid.transpose(),
            grid.azimuth,
            grid.elevation,
        )
    })
}

/// [`prepare_and_insert`] for a map: each prepared scan `apply`'d to `tree`
/// in order, then the tree's memory checked against the build's budget and
/// `done` told. The first failure (a scan that cannot be prepared, a map
/// past its budget) stops the applying and is returned.
fn insert_scans<T: Send>(
    tree: &mut Octree,
    count: usize,
    extras: &BuildExtras,
    prepare: impl Fn(usize) -> std::result::Result<T, String> + Sync,
    mut apply: impl FnMut(&mut Octree, T) + Send,
) -> Result<()> {
    let limit = extras.max_bytes.unwrap_or(MAX_MAP_BYTES);
    let (mut failure, mut inserted) = (None, 0);
    prepare_and_insert(count, window(), prepare, |prepared| match prepared {
        Ok(_) if failure.is_some() => {}
        Ok(scan) => {
            apply(tree, scan);
            inserted += 1;
            if tree.pool_bytes() > limit {
                failure = Some(outgrown(tree, limit, inserted, count));
            }
            if let Some(done) = extras.done {
                done(inserted);
            }
        }
        Err(e) => {
            failure.get_or_insert(e);
        }
    });
    failure.map_or(Ok(()), |e| Err(Error::Usage(e)))
}

/// The last of the `spare` buffers, if any.
fn pop<T>(spare: &Mutex<Vec<T>>) -> Option<T> {
    spare.lock().ok().and_then(|mut s| s.pop())
}

/// The OPDF merge of every scan's grids: each scan's grids are built and
/// searched (on the tree's geometry alone) while earlier scans' changes are
/// applied; the grids' and the plans' memory is reused from scan to scan.
fn opdf_map(
    view: &MapperView,
    scans: &[Scan],
    extras: BuildExtras,
    method: Method,
    resolution: f64,
    offset: &Vector3,
) -> Result<Octree> {
    let mut tree = Octree::new(resolution);
    let options = view.settings.merge_options();
    let geometry = Octree::new(resolution);
    let nominal = shared_nominal_bins(view);
    let spare_grids = Mutex::new(Vec::<GridBuffers>::new());
    let spare_plans = Mutex::new(Vec::<MergePlan>::new());
    let phases = extras.phases;
    let search = |i: usize| -> std::result::Result<Vec<MergePlan>, String> {
        let scan = PreparedScan::new(view, scans, i, extras, method)?;
        let mut plans = Vec::with_capacity(scan.layout.grids.len());
        for grid in &scan.layout.grids {
            let buffers = pop(&spare_grids).unwrap_or_default();
            let local = timed(phases, Phase::Grid, || {
                scan.local_grid(view, extras, i, grid, (nominal.as_ref(), buffers), offset)
            });
            let surfaces = timed(phases, Phase::Index, || {
                SurfaceCells::new(&local, &options.model, &geometry)
            });
            let mut plan = pop(&spare_plans).unwrap_or_default();
            timed(phases, Phase::Search, || {
                plan.search(&geometry, &local, &surfaces, &options);
            });
            if let Ok(mut spare) = spare_grids.lock() {
                spare.push(local.into_buffers());
            }
            plans.push(plan);
        }
        Ok(plans)
    };
    insert_scans(&mut tree, scans.len(), &extras, search, |tree, plans| {
        for plan in plans {
            timed(phases, Phase::Apply, || plan.apply(tree, options.clamp));
            if let Ok(mut spare) = spare_plans.lock() {
                spare.push(plan);
            }
        }
    })?;
    Ok(tree)
}

/// `work()`, its time added to `phase` of `phases` if given.
fn timed<T>(phases: Option<&PhaseTimes>, phase: Phase, work: impl FnOnce() -> T) -> T {
    match phases {
        Some(times) => times.time(phase, work),
        None => work(),
    }
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
fn take_shared_motion(
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

mod phases;
#[cfg(test)]
mod tests;
