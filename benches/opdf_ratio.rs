//! The OPDF merge's time against the ray update's on the same scans: the
//! OctoMap benchmark's (`experiments/octomap_bench.toml`, 696 008 beams, the
//! paper's map settings) at 1, 2 and 5 cm, one core. Each round maps the
//! scans with the ray update, then with the unscented OPDF merge (each the
//! best of two maps), so that the machine's drift falls on both; printed:
//! the median times and the mean of the rounds' ratios (unscented / ray
//! update) with its 95% t-interval, against the target of at most 2x
//! (docs/performance.md, "Where the ray update's time goes"); then, per
//! resolution, where one unscented map's and one ray update's time goes
//! (their steps summed over the scans, the least of three maps), and how
//! much of the target the merge's per-beam steps (its grids and their
//! index) leave its search and apply.

mod common;

use common::{best_of, map_on, mean_and_half_width, median, octomap_bench};
use sigmap::mapping::build::{Phase, PhaseTimes};
use sigmap::mapping::{BuildExtras, Method};

/// Alternating rounds per resolution.
const ROUNDS: usize = 6;
/// Student's t, 97.5% quantile, `ROUNDS - 1` degrees of freedom.
const T_5: f64 = 2.571;
/// The most the OPDF merge may take, in ray updates' times.
const TARGET: f64 = 2.0;

fn main() {
    let (experiment, run) = octomap_bench();
    let beams: usize = run.scans.iter().map(|s| s.measurements.len()).sum();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let map = |method, resolution| {
        map_on(
            &one,
            &experiment,
            &run,
            (method, resolution),
            BuildExtras::default(),
        )
    };
    println!(
        "the OPDF merge (unscented) against the ray update on the OctoMap benchmark's {beams} beams, one core \
         ({ROUNDS} alternating rounds, each the best of 2 maps; ratio: unscented time / ray update time):"
    );
    for resolution in [0.05, 0.02, 0.01] {
        let best = |method| best_of(2, || map(method, resolution));
        let rounds: Vec<(f64, f64)> = (0..ROUNDS)
            .map(|_| {
                let ray = best(Method::RayUpdate);
                (ray, best(Method::Unscented))
            })
            .collect();
        let ratios: Vec<f64> = rounds.iter().map(|(ray, opdf)| opdf / ray).collect();
        let (mean, half) = mean_and_half_width(&ratios, T_5);
        let verdict = if mean + half <= TARGET {
            "met"
        } else if mean - half > TARGET {
            "not met"
        } else {
            "within the noise"
        };
        println!(
            "  {:>4} cm: ray update {:.3} s, unscented {:.3} s (medians): {mean:.2}x [{:.2}, {:.2}] (target at most {TARGET}x: {verdict})",
            resolution * 100.0,
            median(rounds.iter().map(|r| r.0).collect()),
            median(rounds.iter().map(|r| r.1).collect()),
            mean - half,
            mean + half,
        );
        // Where each map's time goes: each step the least of three maps.
        let mut merge_steps = Vec::new();
        for (method, phases) in [
            (Method::Unscented, &Phase::ALL[..]),
            (Method::RayUpdate, &Phase::RAY_UPDATE[..]),
        ] {
            let mut least = vec![f64::INFINITY; phases.len()];
            for _ in 0..3 {
                let times = PhaseTimes::default();
                let extras = BuildExtras {
                    phases: Some(&times),
                    ..BuildExtras::default()
                };
                drop(map_on(
                    &one,
                    &experiment,
                    &run,
                    (method, resolution),
                    extras,
                ));
                for (l, &phase) in least.iter_mut().zip(phases) {
                    *l = l.min(times.seconds(phase));
                }
            }
            let steps: Vec<String> = phases
                .iter()
                .zip(&least)
                .map(|(phase, s)| format!("{} {:.1} ms", phase.as_str(), s * 1e3))
                .collect();
            println!("          {method}'s steps: {}", steps.join(", "));
            if method == Method::Unscented {
                merge_steps = least;
            }
        }
        // The merge's per-beam steps (its grids and their index, each the
        // least of three) against the whole ray update (its fastest map):
        // what the target leaves the search and apply.
        let ray = rounds.iter().map(|r| r.0).fold(f64::INFINITY, f64::min);
        let opdf = &merge_steps;
        let per_beam = opdf[0] + opdf[1];
        let room = TARGET * ray - per_beam;
        let left = if room >= 0.0 {
            format!("leaves the search and apply {:.1} ms", room * 1e3)
        } else {
            format!("is passed by {:.1} ms before any search", -room * 1e3)
        };
        println!(
            "          the grids and index alone take {:.2}x the ray update's fastest map: at most {TARGET}x {left} (the search and apply take {:.1} ms)",
            per_beam / ray,
            (opdf[2] + opdf[3]) * 1e3,
        );
    }
}
