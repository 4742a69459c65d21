//! `sigmap run`: every seed of an experiment, every method on each seed's
//! scans (common random numbers), scored against the ground truth.

use crate::error::{Error, Result};
use crate::eval::ground_truth::{voxelise_at, voxelise_within, KeyBox};
use crate::eval::observable::observable_cells;
use crate::eval::scores::{score_map, MapScores};
use crate::experiment::run::consensus_truth::consensus_truth;
use crate::experiment::run::external::MapperRun;
use crate::experiment::run::registration_belief::registration_belief;
use crate::experiment::study::metrics::Measured;
use crate::experiment::{simulate, Experiment, RunMethod, RunTruth, SimulatedRun};
use crate::geometry::{Isometry3, Matrix3, Vector3};
use crate::mapping::measured::{hit_point, measured_ranges};
use crate::mapping::method::{propagator, scan_chain};
use crate::mapping::pooling::Pooled;
use crate::mapping::{build_map_with, BuildExtras, Method, Octree, TreeStats};
use crate::sim::scan::ScanTruth;
use crate::uncertainty::consistency::{nees, ConsistencyReport};
use crate::uncertainty::{Propagator, RangeModel};
use rustc_hash::FxHashSet;
use serde::{Deserialize, Serialize};
use std::time::Instant;

pub use crate::experiment::study::metrics::RunRow;

/// Stage timings of one (seed, method), for `timings.csv` (they vary run to run).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TimingRow {
    /// The sweep cell.
    pub cell: String,
    /// The run's seed.
    pub seed: u64,
    /// The method.
    pub method: String,
    /// Simulation (shared by the seed's methods).
    pub simulate_s: f64,
    /// Map building.
    pub model_s: f64,
    /// Scoring.
    pub score_s: f64,
}

/// The truth the run with `seed` is scored against (in its map frame,
/// `Experiment::map_offset`).
pub fn ground_truth(experiment: &Experiment, seed: u64) -> Octree {
    voxelise_at(
        experiment.scene(),
        experiment.resolution(),
        &experiment.map_offset(seed),
    )
}

/// The truth as the run's scene registration places it: the scene moved by
/// the drawn registration error, `map = offset + T̂_sw⁻¹ T_sw · scene`
/// (T̂_sw nominal, T_sw the run's draw). What a perfect sensor on a perfect
/// arm with an exact hand-eye calibration would map: the reference method
/// `registered_truth`, the ceiling for a map that cannot see the
/// registration error (docs/math.md §7.5). The truth itself without it.
/// Computed over the finest cells of `region` (every other one unknown).
pub fn registered_truth(
    experiment: &Experiment,
    truth: &RunTruth,
    resolution: f64,
    offset: &Vector3,
    region: &KeyBox,
) -> Octree {
    let map_from_scene = registered_placement(experiment, truth, offset);
    voxelise_within(experiment.scene(), resolution, &map_from_scene, region)
}

/// The scoring reference `method` of `run` ([`Method::is_truth`]) over the
/// finest cells of `region`: [`registered_truth`], [`consensus_truth`] or
/// [`registration_belief`];
/// `None` for a method that maps the scans.
pub fn truth_reference(
    method: Method,
    experiment: &Experiment,
    run: &SimulatedRun,
    offset: &Vector3,
    region: &KeyBox,
) -> Option<Octree> {
    let resolution = experiment.resolution();
    match method {
        Method::RegisteredTruth => Some(registered_truth(
            experiment, &run.truth, resolution, offset, region,
        )),
        Method::ConsensusTruth => Some(consensus_truth(
            experiment, &run.scans, &run.truth, offset, region,
        )),
        Method::RegistrationBelief => Some(registration_belief(
            experiment, &run.truth, run.seed, offset, region,
        )),
        _ => None,
    }
}

/// The truth a run is scored against, computed over the box of finest
/// cells that spans its observable mask (the same value on every scored
/// cell as [`ground_truth`], in time and memory that follow the observed
/// volume, not the workspace).
pub fn run_truth(experiment: &Experiment, seed: u64, region: &KeyBox) -> Octree {
    let offset = experiment.map_offset(seed);
    voxelise_within(
        experiment.scene(),
        experiment.resolution(),
        &Isometry3::translation(offset.x, offset.y, offset.z),
        region,
    )
}

/// What one seed's runs give: a row and timings per method, each method's
/// map, and the truth they were scored against.
pub struct SeedOutcome {
    /// One row per method.
    pub rows: Vec<RunRow>,
    /// One timing row per method.
    pub timings: Vec<TimingRow>,
    /// Each method's map.
    pub maps: Vec<Octree>,
    /// The truth ([`run_truth`]).
    pub truth: Octree,
    /// The cells it was computed over: the box its observable mask spans.
    pub region: KeyBox,
    /// The scored cells (Morton codes): the observable mask.
    pub observable: FxHashSet<u64>,
}

/// Where the run's registration places the scene in the map frame:
/// `map_from_scene = offset · T̂_sw⁻¹ T_sw` (see [`registered_truth`]).
pub fn registered_placement(
    experiment: &Experiment,
    truth: &RunTruth,
    offset: &Vector3,
) -> Isometry3 {
    Isometry3::translation(offset.x, offset.y, offset.z)
        * experiment.world_from_scene().to_isometry().inverse()
        * truth.world_from_scene
}

/// The cells some true beam of the run could have seen (the scoring mask).
pub fn observable(
    experiment: &Experiment,
    truths: &[ScanTruth],
    offset: &Vector3,
) -> FxHashSet<u64> {
    observable_cells(
        experiment.scanner().directions(),
        experiment.scanner().max_range,
        truths,
        experiment.resolution(),
        offset,
    )
}

/// Runs one seed: simulate, then build, score and check each method.
/// Returns the rows, the timings and the maps (in `experiment.methods` order).
pub fn run_seed(experiment: &Experiment, seed: u64) -> Result<SeedOutcome> {
    let start = Instant::now();
    let seed_run = SeedRun::new(experiment, seed)?;
    let truth = run_truth(experiment, seed, &seed_run.region);
    let simulate_s = start.elapsed().as_secs_f64();
    let cell = Experiment::cell_label(experiment.cell());
    let (mut rows, mut timings, mut maps) = (Vec::new(), Vec::new(), Vec::new());
    for method in experiment.methods() {
        let start = Instant::now();
        let map = seed_run.map(method, &cell)?;
        let model_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let scores: MapScores = score_map(&map, &truth, &seed_run.observable);
        let pairs = method.own().map_or_else(Vec::new, |m| seed_run.errors(m));
        // Points of one viewpoint share its pose error: the χ² bounds of
        // the consistency report do not apply to the run's points as one.
        let consistency =
            (!pairs.is_empty()).then(|| ConsistencyReport::new(pairs.iter().map(|(e, c)| (*e, c))));
        let nees_point = pairs.first().map_or(f64::NAN, |(e, c)| nees(e, c));
        let score_s = start.elapsed().as_secs_f64();
        let stats = map.stats();
        if let RunMethod::External(mapper) = method {
            check_frame(&scores, &stats).map_err(|what| {
                Error::Usage(format!(
                    "mapper {} (cell {cell}, seed {seed}): {what}",
                    mapper.name
                ))
            })?;
        }
        let measured = Measured {
            scores: &scores,
            consistency: consistency.as_ref(),
            nees_point,
            stats: &stats,
        };
        let name = method.as_str();
        rows.push(RunRow::new(
            cell.clone(),
            seed,
            name,
            experiment.resolution(),
            &measured,
        ));
        timings.push(TimingRow {
            cell: cell.clone(),
            seed,
            method: name.into(),
            simulate_s,
            model_s,
            score_s,
        });
        maps.push(map);
    }
    Ok(SeedOutcome {
        rows,
        timings,
        maps,
        truth,
        region: seed_run.region,
        observable: seed_run.observable,
    })
}

/// One seed's simulated run, with what every method of it shares: the
/// map offset, the scoring mask and the scans' measured ranges.
struct SeedRun<'a> {
    experiment: &'a Experiment,
    seed: u64,
    run: SimulatedRun,
    offset: Vector3,
    observable: FxHashSet<u64>,
    /// The box of cells the mask spans, which the truths are computed over.
    region: KeyBox,
    measured: Vec<Vec<Pooled>>,
}

impl<'a> SeedRun<'a> {
    fn new(experiment: &'a Experiment, seed: u64) -> Result<Self> {
        let run = simulate(experiment, seed, |_| {})?;
        let offset = experiment.map_offset(seed);
        let observable = observable(experiment, &run.truth.scans, &offset);
        let region = KeyBox::spanning(observable.iter().copied());
        // What each scan measured (pooled or not): the same for every method.
        let view = experiment.mapper_view();
        let measured = run
            .scans
            .iter()
            .map(|scan| measured_ranges(&view, &experiment.scanner().layout, scan))
            .collect::<std::result::Result<_, _>>()
            .map_err(Error::Usage)?;
        Ok(Self {
            experiment,
            seed,
            run,
            offset,
            observable,
            region,
            measured,
        })
    }

    /// The map of `method`: sigmap's own builder, a truth reference, or an
    /// external mapper run on the exported scans.
    fn map(&self, method: &RunMethod, cell: &str) -> Result<Octree> {
        let experiment = self.experiment;
        let view = experiment.mapper_view();
        match method {
            RunMethod::Own(method) => {
                let region = &self.region;
                if let Some(tree) =
                    truth_reference(*method, experiment, &self.run, &self.offset, region)
                {
                    return Ok(tree);
                }
                let extras = BuildExtras {
                    measured: Some(&self.measured),
                    done: None,
                    max_bytes: None,
                    phases: None,
                };
                let scans = &self.run.scans;
                build_map_with(
                    &view,
                    scans,
                    extras,
                    *method,
                    experiment.resolution(),
                    &self.offset,
                )
            }
            RunMethod::External(mapper) => mapper.build(&MapperRun {
                cell,
                seed: self.seed,
                view: &view,
                scans: &self.run.scans,
                resolution: experiment.resolution(),
                offset: &self.offset,
                clamp: experiment.map().clamp(),
                camera: experiment.scanner().camera.as_ref(),
            }),
        }
    }

    /// Propagated points of `method` against the true surface points: the
    /// error and covariance of every hit (none for a method that
    /// propagates nothing).
    fn errors(&self, method: Method) -> Vec<(Vector3, Matrix3)> {
        let experiment = self.experiment;
        let mut pairs = Vec::new();
        let scans = self.run.scans.iter().zip(&self.run.truth.scans);
        for ((scan, truth), points) in scans.zip(&self.measured) {
            if let Some(p) = propagator(method, &scan_chain(scan), experiment.sigma_set()) {
                pairs.extend(errors_against_truth(
                    &experiment.mapper_view().range,
                    experiment.scanner().directions(),
                    truth,
                    points,
                    p.as_ref(),
                ));
            }
        }
        pairs
    }
}

/// Refuses an external map that knows almost none of the run's observable
/// cells though it knows cells: it is in another frame than the export's.
fn check_frame(scores: &MapScores, stats: &TreeStats) -> std::result::Result<(), String> {
    let known_leaves = stats.leaves;
    if known_leaves > 0 && scores.unknown_fraction > 0.99 {
        return Err(format!(
            "its map knows {known_leaves} cells but {:.1}% of the run's observable cells are \
             unknown in it: it is not in the map frame of the exported scans (scans.graph's \
             poses, the scene frame shifted by the run's grid offset)",
            100.0 * scores.unknown_fraction
        ));
    }
    Ok(())
}

/// For each hit of a scan (its measured ranges, as [`hit_point`]s): the
/// error `true hit − propagated mean` and the propagated covariance, for
/// consistency checks against the simulator.
fn errors_against_truth(
    range: &RangeModel,
    directions: &[Vector3],
    truth: &ScanTruth,
    ranges: &[Pooled],
    propagator: &dyn Propagator,
) -> Vec<(Vector3, Matrix3)> {
    ranges
        .iter()
        .zip(directions)
        .zip(&truth.beams)
        .filter_map(|((p, d), t)| {
            let g = propagator.propagate(&hit_point(range, d, p.as_ref()?));
            Some((t.point.coords - g.mean, g.covariance))
        })
        .collect()
}

/// Reads the rows of an existing `runs.csv` (empty if absent).
pub fn read_rows<T: for<'de> Deserialize<'de>>(path: &std::path::Path) -> Result<Vec<T>> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let mut reader = csv::Reader::from_path(path).map_err(|e| Error::input(path, e))?;
    reader
        .deserialize()
        .collect::<std::result::Result<Vec<T>, _>>()
        .map_err(|e| {
            Error::input(
                path,
                format!("cannot read the rows ({e}); the results must be computed afresh"),
            )
        })
}

/// Appends `row` to the runs.csv-shaped file at `path` (created if absent),
/// staged and renamed. A file whose header is not runs.csv's is refused, so
/// no column of a file sigmap did not write is ever dropped.
pub fn append_row(path: &std::path::Path, row: &RunRow) -> Result<()> {
    if path.exists() {
        let text = crate::error::read_text(path)?;
        let first = text.lines().next().unwrap_or("");
        if first != crate::experiment::study::metrics::header() {
            return Err(Error::input(
                path,
                "its header is not the runs.csv columns of this sigmap, and sigmap appends only \
                 to a file of its own",
            ));
        }
    }
    let mut rows: Vec<RunRow> = read_rows(path)?;
    rows.push(row.clone());
    write_rows(path, &rows)
}

/// Writes rows as CSV into `path` atomically (staged, then renamed; see
/// [`crate::files::write_file`]).
pub fn write_rows<T: Serialize>(path: &std::path::Path, rows: &[T]) -> Result<()> {
    let mut bytes = Vec::new();
    {
        let mut w = csv::Writer::from_writer(&mut bytes);
        for row in rows {
            w.serialize(row).map_err(|e| Error::io(path, e.into()))?;
        }
        w.flush().map_err(|e| Error::io(path, e))?;
    }
    crate::files::write_file(path, &bytes)
}

/// The quickstart with the error profile `profile` (its TOML after the
/// name), `grid_offset = true`, and `extra` appended to the experiment's
/// top-level keys; written into `dir` and loaded.
#[cfg(test)]
pub(crate) fn quickstart_with_profile(
    dir: &std::path::Path,
    profile: &str,
    extra: &str,
) -> Experiment {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let profile_path = dir.join("profile.toml");
    std::fs::write(&profile_path, format!("name = \"test\"\n{profile}")).unwrap();
    let text = std::fs::read_to_string(root.join("experiments/quickstart.toml"))
        .unwrap()
        .replace("\"../", &format!("\"{}/", root.display()))
        .replace(
            "profiles/collaborative.toml",
            &profile_path.display().to_string(),
        )
        .replace(
            "resolution = 0.01",
            &format!("resolution = 0.01\ngrid_offset = true\n{extra}"),
        );
    let path = dir.join("experiment.toml");
    std::fs::write(&path, text).unwrap();
    Experiment::load(&path).unwrap()
}

#[cfg(test)]
mod tests;
