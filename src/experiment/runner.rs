//! `sigmap run`: every seed of an experiment, every method on each seed's
//! scans (common random numbers), scored against the ground truth.

use super::model::{
    beam_ends_with_truth, build_map_measured, measured_points, propagator, scan_chain, Method,
};
use super::{simulate, Experiment};
use crate::error::{Error, Result};
use crate::eval::ground_truth::voxelise_at;
use crate::eval::observable::observable_cells;
use crate::eval::scores::{score_map, MapScores};
use crate::mapping::Octree;
use crate::uncertainty::consistency::{nees, student_t_quantile, ConsistencyReport};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One row of `runs.csv`: a seed, a method, and every score.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunRow {
    /// The sweep cell, `field=value;...` (empty without a sweep).
    pub cell: String,
    /// The run's seed.
    pub seed: u64,
    /// The modelling method.
    pub method: String,
    /// Map resolution (m).
    pub resolution: f64,
    /// Observable cells scored.
    pub observable_cells: usize,
    /// Truly occupied observable cells.
    pub occupied_cells: usize,
    /// Occupied precision.
    pub precision: f64,
    /// Occupied recall.
    pub recall: f64,
    /// Occupied F1.
    pub f1: f64,
    /// Occupied IoU.
    pub iou: f64,
    /// Truly occupied cells called free / truly occupied.
    pub false_free_rate: f64,
    /// The same within one cell of a surface.
    pub false_free_rate_margin: f64,
    /// Truly free cells called occupied / truly free.
    pub false_occupied_rate: f64,
    /// Unknown / observable.
    pub unknown_fraction: f64,
    /// Brier score.
    pub brier: f64,
    /// Log-loss.
    pub log_loss: f64,
    /// ROC AUC.
    pub roc_auc: f64,
    /// ANEES of the propagated points against the true surface points (NaN for ray_update).
    pub anees: f64,
    /// Two-sided 95% χ² band of ANEES for this many independent points; the
    /// points of a viewpoint share its pose error, so read it as a reference.
    pub anees_low: f64,
    /// Upper end of that band.
    pub anees_high: f64,
    /// NEES of one point of the run (the first hit of the first viewpoint):
    /// independent across seeds, so its mean over N seeds has the χ²₃ₙ/N
    /// band that the run's ANEES does not (docs/math.md §6.6).
    pub nees_point: f64,
    /// Share of true points inside the 1, 2, 3 sigma ellipsoids.
    pub coverage_1sigma: f64,
    /// See `coverage_1sigma`.
    pub coverage_2sigma: f64,
    /// See `coverage_1sigma`.
    pub coverage_3sigma: f64,
    /// Octree nodes.
    pub nodes: usize,
    /// Octree bytes.
    pub bytes: usize,
}

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
        &experiment.scene,
        experiment.resolution,
        &experiment.map_offset(seed),
    )
}

/// Runs one seed: simulate, then build, score and check each method.
/// Returns the rows, the timings and the maps (in `experiment.methods` order).
pub fn run_seed(
    experiment: &Experiment,
    truth: &Octree,
    seed: u64,
) -> Result<(Vec<RunRow>, Vec<TimingRow>, Vec<Octree>)> {
    let start = Instant::now();
    let run = simulate(experiment, seed, |_| {})?;
    let simulate_s = start.elapsed().as_secs_f64();
    let offset = experiment.map_offset(seed);
    let observable = observable_cells(
        &experiment.scanner.directions,
        experiment.scanner.max_range,
        run.scans.iter().map(|scan| &scan.truth),
        experiment.resolution,
        &offset,
    );
    // What each scan measured (pooled or not): the same for every method.
    let measured: Vec<_> = run
        .scans
        .iter()
        .map(|scan| measured_points(experiment, scan))
        .collect();
    let (mut rows, mut timings, mut maps) = (Vec::new(), Vec::new(), Vec::new());
    for &method in &experiment.methods {
        let start = Instant::now();
        let map = build_map_measured(
            experiment,
            &run,
            &measured,
            method,
            experiment.resolution,
            &offset,
        )?;
        let model_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let s: MapScores = score_map(&map, truth, &observable);
        // Propagated points against the true surface points. Points of one
        // viewpoint share its pose error: the χ² bounds do not apply here.
        let mut pairs = Vec::new();
        for (scan, points) in run.scans.iter().zip(&measured) {
            if let Some(p) = propagator(method, &scan_chain(scan)) {
                pairs.extend(beam_ends_with_truth(scan, points, p.as_ref()));
            }
        }
        let consistency =
            (!pairs.is_empty()).then(|| ConsistencyReport::new(pairs.iter().map(|(e, c)| (*e, c))));
        let nees_point = pairs.first().map_or(f64::NAN, |(e, c)| nees(e, c));
        let score_s = start.elapsed().as_secs_f64();
        let stats = map.stats();
        let c = |f: fn(&ConsistencyReport) -> f64| consistency.as_ref().map_or(f64::NAN, f);
        let cell = Experiment::cell_label(&experiment.cell);
        rows.push(RunRow {
            cell: cell.clone(),
            seed,
            method: method.as_str().into(),
            resolution: experiment.resolution,
            observable_cells: s.observable_cells,
            occupied_cells: s.occupied_cells,
            precision: s.precision,
            recall: s.recall,
            f1: s.f1,
            iou: s.iou,
            false_free_rate: s.false_free_rate,
            false_free_rate_margin: s.false_free_rate_margin,
            false_occupied_rate: s.false_occupied_rate,
            unknown_fraction: s.unknown_fraction,
            brier: s.brier,
            log_loss: s.log_loss,
            roc_auc: s.roc_auc,
            anees: c(|r| r.anees),
            anees_low: c(|r| r.bounds.0),
            anees_high: c(|r| r.bounds.1),
            nees_point,
            coverage_1sigma: c(|r| r.coverage[0]),
            coverage_2sigma: c(|r| r.coverage[1]),
            coverage_3sigma: c(|r| r.coverage[2]),
            nodes: stats.nodes,
            bytes: stats.bytes,
        });
        timings.push(TimingRow {
            cell,
            seed,
            method: method.as_str().into(),
            simulate_s,
            model_s,
            score_s,
        });
        maps.push(map);
    }
    Ok((rows, timings, maps))
}

/// The metrics summarised in `summary.csv`.
pub const SUMMARY_METRICS: [&str; 16] = [
    "precision",
    "recall",
    "f1",
    "iou",
    "false_free_rate",
    "false_free_rate_margin",
    "false_occupied_rate",
    "unknown_fraction",
    "brier",
    "log_loss",
    "roc_auc",
    "anees",
    "nees_point",
    "coverage_1sigma",
    "coverage_2sigma",
    "coverage_3sigma",
];

fn metric(row: &RunRow, name: &str) -> f64 {
    match name {
        "precision" => row.precision,
        "recall" => row.recall,
        "f1" => row.f1,
        "iou" => row.iou,
        "false_free_rate" => row.false_free_rate,
        "false_free_rate_margin" => row.false_free_rate_margin,
        "false_occupied_rate" => row.false_occupied_rate,
        "unknown_fraction" => row.unknown_fraction,
        "brier" => row.brier,
        "log_loss" => row.log_loss,
        "roc_auc" => row.roc_auc,
        "anees" => row.anees,
        "nees_point" => row.nees_point,
        "coverage_1sigma" => row.coverage_1sigma,
        "coverage_2sigma" => row.coverage_2sigma,
        "coverage_3sigma" => row.coverage_3sigma,
        _ => f64::NAN,
    }
}

/// One row of `summary.csv`: a method's mean and 95% interval of a metric
/// over the seeds (Student t; a single seed has no interval).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SummaryRow {
    /// The sweep cell.
    pub cell: String,
    /// The method.
    pub method: String,
    /// The metric (a `runs.csv` column).
    pub metric: String,
    /// Seeds with a finite value.
    pub n: usize,
    /// Mean over the seeds.
    pub mean: f64,
    /// Lower end of the 95% interval of the mean.
    pub ci95_low: f64,
    /// Upper end.
    pub ci95_high: f64,
}

/// Per cell (in `cells` order), method and metric: mean and 95% interval
/// over the rows' seeds.
pub fn summarise(rows: &[RunRow], cells: &[String], methods: &[Method]) -> Vec<SummaryRow> {
    let mut out = Vec::new();
    for (cell, method) in cells
        .iter()
        .flat_map(|c| methods.iter().map(move |m| (c, m)))
    {
        let mine: Vec<&RunRow> = rows
            .iter()
            .filter(|r| &r.cell == cell && r.method == method.as_str())
            .collect();
        for name in SUMMARY_METRICS {
            let values: Vec<f64> = mine
                .iter()
                .map(|r| metric(r, name))
                .filter(|v| v.is_finite())
                .collect();
            let n = values.len();
            let mean = values.iter().sum::<f64>() / n as f64;
            let half = if n >= 2 {
                let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
                student_t_quantile((n - 1) as f64, 0.975) * (var / n as f64).sqrt()
            } else {
                f64::NAN
            };
            out.push(SummaryRow {
                cell: cell.clone(),
                method: method.as_str().into(),
                metric: name.into(),
                n,
                mean,
                ci95_low: mean - half,
                ci95_high: mean + half,
            });
        }
    }
    out
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
                format!("cannot read the rows ({e}); rerun with --fresh"),
            )
        })
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles() {
        assert!((student_t_quantile(1.0, 0.975) - 12.706).abs() < 1e-3);
        assert!((student_t_quantile(9.0, 0.975) - 2.262).abs() < 1e-3);
        assert!((student_t_quantile(1000.0, 0.975) - 1.962).abs() < 1e-3);
    }
}
