//! What the map benches share: the OctoMap benchmark's scans, the best time
//! of a few maps, and the mean of paired rounds' ratios with its 95%
//! t-interval.

use sigmap::experiment::{simulate, Experiment, SimulatedRun};
use sigmap::geometry::Vector3;
use sigmap::mapping::{build_map_with, BuildExtras, Method, Octree};
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

/// `experiments/octomap_bench.toml` (the paper's map settings) and its
/// first run.
pub fn octomap_bench() -> (Experiment, SimulatedRun) {
    let experiment = Experiment::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/octomap_bench.toml"
    )))
    .expect("octomap_bench");
    let run = simulate(&experiment, 1, |_| {}).expect("simulate");
    (experiment, run)
}

/// One map of `run`'s scans on `pool`.
pub fn map_on(
    pool: &rayon::ThreadPool,
    experiment: &Experiment,
    run: &SimulatedRun,
    (method, resolution): (Method, f64),
    extras: BuildExtras,
) -> Octree {
    let view = experiment.mapper_view();
    pool.install(|| {
        build_map_with(
            &view,
            &run.scans,
            extras,
            method,
            resolution,
            &Vector3::zeros(),
        )
        .expect("the bench maps")
    })
}

/// The least time (s) of `n` calls of `build`; each map is freed after
/// the clock stops, so that its building alone is timed.
pub fn best_of(n: usize, build: impl Fn() -> Octree) -> f64 {
    (0..n)
        .map(|_| {
            let start = Instant::now();
            let tree = black_box(build());
            let seconds = start.elapsed().as_secs_f64();
            drop(tree);
            seconds
        })
        .fold(f64::INFINITY, f64::min)
}

/// The mean of `ratios` and the half-width of its 95% t-interval, with `t`
/// Student's 97.5% quantile for `ratios.len() − 1` degrees of freedom.
pub fn mean_and_half_width(ratios: &[f64], t: f64) -> (f64, f64) {
    let n = ratios.len() as f64;
    let mean = ratios.iter().sum::<f64>() / n;
    let sd = (ratios.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    (mean, t * sd / n.sqrt())
}

/// The median of `values`.
pub fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        (values[n / 2 - 1] + values[n / 2]) / 2.0
    }
}
