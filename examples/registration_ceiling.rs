//! What the scene registration error alone costs a map, at every threshold
//! (docs/math.md §7.5):
//!
//!     registration_ceiling EXPERIMENT POSE_ERROR_SCALE SEEDS DRAWS
//!
//! For seeds 1..=SEEDS: the true occupancy as the run's drawn registration
//! (T_sw) places it, blurred over DRAWS further draws of the registration
//! error as the maps are told it (what a map that knows the registration's
//! covariance, and nothing else wrong, would believe; the drawn one unless
//! the experiment's `[believed]` says otherwise), called occupied where that belief exceeds τ,
//! scored against the truth on the run's observable cells. Prints, per τ,
//! the mean precision, false-free rate and F1, and each one's paired
//! difference from the registered truth (the reference method
//! `registered_truth`, the same seeds) with its 95% Student t interval.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sigmap::eval::ground_truth::{voxelise_within, KeyBox};
use sigmap::eval::scores::{score_map, UNKNOWN_BAND};
use sigmap::experiment::run::runner::{observable, registered_placement, run_truth};
use sigmap::experiment::study::metrics::Better;
use sigmap::experiment::study::summary::PairedDifference;
use sigmap::experiment::{simulate, Experiment, SweepValue};
use sigmap::mapping::octree::DEPTH;
use sigmap::mapping::Key;
use sigmap::sim::truth::draw_pose;
use sigmap::uncertainty::UncertainPose;
use std::path::Path;

const THRESHOLDS: [f64; 14] = [
    0.02, 0.1, 0.2, 0.3, 0.35, 0.4, 0.45, 0.475, 0.5, 0.55, 0.6, 0.7, 0.8, 0.9,
];

/// Precision, false-free rate and F1, with the direction each improves in.
const SCORES: [(&str, Better); 3] = [
    ("precision", Better::Higher),
    ("false_free_rate", Better::Lower),
    ("f1", Better::Higher),
];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let parsed = (args.len() == 5)
        .then(|| {
            Some((
                args[2].parse::<f64>().ok()?,
                args[3].parse::<u64>().ok()?,
                args[4].parse::<usize>().ok().filter(|&k| k > 0)?,
            ))
        })
        .flatten();
    let Some((scale, seeds, draws)) = parsed else {
        eprintln!("usage: registration_ceiling EXPERIMENT POSE_ERROR_SCALE SEEDS DRAWS");
        std::process::exit(2);
    };
    let cell = [("pose_error_scale".to_string(), SweepValue::Number(scale))];
    let result = Experiment::load_cell(Path::new(&args[1]), &cell)
        .and_then(|experiment| ceiling(&experiment, seeds, draws));
    let per_seed = match result {
        Ok(per_seed) => per_seed,
        Err(e) => {
            eprintln!("registration_ceiling: {e}");
            std::process::exit(2);
        }
    };
    print!("tau");
    for (name, _) in SCORES {
        print!(",{name},{name}_minus_registered,ci95_low,ci95_high");
    }
    println!();
    let registered = &per_seed.registered;
    let rows = std::iter::once(("registered_truth".to_string(), registered)).chain(
        THRESHOLDS
            .iter()
            .zip(&per_seed.blurred)
            .map(|(t, s)| (t.to_string(), s)),
    );
    for (label, scores) in rows {
        print!("{label}");
        for (index, (_, better)) in SCORES.iter().enumerate() {
            let column = |s: &[(u64, [f64; 3])]| -> Vec<(u64, f64)> {
                s.iter().map(|(seed, v)| (*seed, v[index])).collect()
            };
            let mine = column(scores);
            let mean = mine.iter().map(|(_, v)| v).sum::<f64>() / mine.len() as f64;
            match PairedDifference::of(&mine, &column(registered), *better) {
                Some(d) => print!(
                    ",{mean:.4},{:+.4},{:+.4},{:+.4}",
                    d.mean, d.ci95.0, d.ci95.1
                ),
                None => print!(",{mean:.4},,,"),
            }
        }
        println!();
    }
}

/// Per seed, the registered truth's precision, false-free rate and F1, and
/// the blurred belief's at each threshold.
struct Scores {
    registered: Vec<(u64, [f64; 3])>,
    blurred: Vec<Vec<(u64, [f64; 3])>>,
}

fn ceiling(experiment: &Experiment, seeds: u64, draws: usize) -> sigmap::Result<Scores> {
    let mut scores = Scores {
        registered: Vec::new(),
        blurred: vec![Vec::new(); THRESHOLDS.len()],
    };
    let nominal = experiment.world_from_scene().to_isometry();
    // The registration's covariance as the maps are told it ([believed]).
    let registration = UncertainPose {
        mean: experiment.world_from_scene(),
        covariance: experiment.believed_profile().world_from_scene
            * experiment.believed().pose_variance(),
    };
    let resolution = experiment.resolution();
    for seed in 1..=seeds {
        let run = simulate(experiment, seed, |_| {})?;
        let offset = experiment.map_offset(seed);
        let observable = observable(experiment, &run.truth.scans, &offset);
        let region = KeyBox::spanning(observable.iter().copied());
        let truth = run_truth(experiment, seed, &region);
        let registered = registered_placement(experiment, &run.truth, &offset);
        let registered_tree = voxelise_within(experiment.scene(), resolution, &registered, &region);
        // The blur: further registration errors on top of the run's own.
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let blurred: Vec<_> = (0..draws)
            .map(|_| {
                let error = nominal.inverse() * draw_pose(&registration, &mut rng).to_isometry();
                voxelise_within(
                    experiment.scene(),
                    resolution,
                    &(registered * error),
                    &region,
                )
            })
            .collect();
        let votes_for = |tree: &sigmap::mapping::Octree, key: &Key| {
            tree.query(key, DEPTH).is_some_and(|v| v >= UNKNOWN_BAND)
        };
        // Per scored cell: truly occupied, and the registered truth's call
        // (`None` where it does not know the cell, which the belief then
        // leaves unknown too) with the belief.
        let cells: Vec<(bool, Option<(bool, f64)>)> = observable
            .iter()
            .filter_map(|&code| {
                let key = Key::from_morton(code);
                let truly = truth.query(&key, DEPTH)? >= 0.0;
                let known = registered_tree
                    .query(&key, DEPTH)
                    .filter(|v| v.abs() >= UNKNOWN_BAND)
                    .map(|v| {
                        let votes = blurred.iter().filter(|tree| votes_for(tree, &key)).count();
                        (v > 0.0, votes as f64 / draws as f64)
                    });
                Some((truly, known))
            })
            .collect();
        let calls = |called: &dyn Fn((bool, f64)) -> bool| -> [f64; 3] {
            let (mut tp, mut fp, mut fn_, mut false_free) = (0.0, 0.0, 0.0, 0.0);
            for &(truly, known) in &cells {
                let called = known.map(called);
                match (truly, called) {
                    (true, Some(true)) => tp += 1.0,
                    (false, Some(true)) => fp += 1.0,
                    (true, Some(false)) => {
                        fn_ += 1.0;
                        false_free += 1.0;
                    }
                    (true, None) => fn_ += 1.0,
                    (false, _) => {}
                }
            }
            let precision = tp / (tp + fp);
            [
                precision,
                false_free / (tp + fn_),
                2.0 * tp / (2.0 * tp + fp + fn_),
            ]
        };
        let registered_scores = score_map(&registered_tree, &truth, &observable);
        scores.registered.push((
            seed,
            [
                registered_scores.precision,
                registered_scores.false_free_rate,
                registered_scores.f1,
            ],
        ));
        debug_assert_eq!(
            calls(&|(call, _)| call)[1],
            registered_scores.false_free_rate
        );
        for (sums, tau) in scores.blurred.iter_mut().zip(THRESHOLDS) {
            sums.push((seed, calls(&|(_, belief)| belief > tau)));
        }
    }
    Ok(scores)
}
