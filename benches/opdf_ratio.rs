//! The OPDF merge's time against the ray update's on the same scans: the
//! OctoMap benchmark's (`experiments/octomap_bench.toml`, 696 008 beams, the
//! paper's map settings) at 1, 2 and 5 cm, one core. Each round maps the
//! scans with the ray update, then with the unscented OPDF merge (each the
//! best of two maps), so that the machine's drift falls on both; printed:
//! the median times and the mean of the rounds' ratios (unscented / ray
//! update) with its 95% t-interval, against the target of at most 2x
//! (docs/performance.md, "Where the ray update's time goes"); then, per
//! resolution, where one unscented map's time goes (its steps summed over
//! the scans, the least of three maps).

use sigmap::experiment::{simulate, Experiment};
use sigmap::geometry::Vector3;
use sigmap::mapping::build::{Phase, PhaseTimes};
use sigmap::mapping::{build_map, build_map_with, BuildExtras, Method};
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

/// Alternating rounds per resolution.
const ROUNDS: usize = 6;
/// Student's t, 97.5% quantile, `ROUNDS - 1` degrees of freedom.
const T_5: f64 = 2.571;
/// The most the OPDF merge may take, in ray updates' times.
const TARGET: f64 = 2.0;

fn main() {
    let experiment = Experiment::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/octomap_bench.toml"
    )))
    .expect("octomap_bench");
    let run = simulate(&experiment, 1, |_| {}).expect("simulate");
    let view = experiment.mapper_view();
    let beams: usize = run.scans.iter().map(|s| s.measurements.len()).sum();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let best_of_two = |method, resolution| {
        (0..2)
            .map(|_| {
                let start = Instant::now();
                let tree = one.install(|| {
                    build_map(&view, &run.scans, method, resolution, &Vector3::zeros())
                        .expect("the bench maps")
                });
                let seconds = start.elapsed().as_secs_f64();
                // Freed after the clock stops: the map's building is timed.
                drop(black_box(tree));
                seconds
            })
            .fold(f64::INFINITY, f64::min)
    };
    println!(
        "the OPDF merge (unscented) against the ray update on the OctoMap benchmark's {beams} beams, one core \
         ({ROUNDS} alternating rounds, each the best of 2 maps; ratio: unscented time / ray update time):"
    );
    for resolution in [0.05, 0.02, 0.01] {
        let rounds: Vec<(f64, f64)> = (0..ROUNDS)
            .map(|_| {
                let ray = best_of_two(Method::RayUpdate, resolution);
                (ray, best_of_two(Method::Unscented, resolution))
            })
            .collect();
        let ratios: Vec<f64> = rounds.iter().map(|(ray, opdf)| opdf / ray).collect();
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            (v[v.len() / 2 - 1] + v[v.len() / 2]) / 2.0
        };
        let ray = median(rounds.iter().map(|r| r.0).collect());
        let opdf = median(rounds.iter().map(|r| r.1).collect());
        let n = ROUNDS as f64;
        let mean = ratios.iter().sum::<f64>() / n;
        let sd = (ratios.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let half = T_5 * sd / n.sqrt();
        let verdict = if mean + half <= TARGET {
            "met"
        } else if mean - half > TARGET {
            "not met"
        } else {
            "within the noise"
        };
        println!(
            "  {:>4} cm: ray update {ray:.3} s, unscented {opdf:.3} s (medians): {mean:.2}x [{:.2}, {:.2}] (target at most {TARGET}x: {verdict})",
            resolution * 100.0,
            mean - half,
            mean + half,
        );
        // Where an unscented map's time goes: each step the least of three
        // maps.
        let mut least = [f64::INFINITY; 4];
        for _ in 0..3 {
            let times = PhaseTimes::default();
            let extras = BuildExtras {
                phases: Some(&times),
                ..BuildExtras::default()
            };
            let tree = one.install(|| {
                build_map_with(
                    &view,
                    &run.scans,
                    extras,
                    Method::Unscented,
                    resolution,
                    &Vector3::zeros(),
                )
                .expect("the bench maps")
            });
            drop(black_box(tree));
            for (l, phase) in least.iter_mut().zip(Phase::ALL) {
                *l = l.min(times.seconds(phase));
            }
        }
        let steps: Vec<String> = Phase::ALL
            .iter()
            .zip(least)
            .map(|(phase, s)| format!("{} {:.1} ms", phase.as_str(), s * 1e3))
            .collect();
        println!("          unscented's steps: {}", steps.join(", "));
    }
}
