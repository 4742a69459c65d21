//! What the scene registration error alone costs a map, at every threshold
//! (docs/math.md §7.5):
//!
//!     registration_ceiling EXPERIMENT POSE_ERROR_SCALE SEEDS DRAWS
//!
//! For seeds 1..=SEEDS: the true occupancy as the run's drawn registration
//! (T_sw) places it, blurred over DRAWS further draws of the registration
//! error (what a map that knows the registration's covariance, and nothing
//! else wrong, would believe), called occupied where that belief exceeds τ,
//! scored against the truth on the run's observable cells. Prints the mean
//! precision, false-free rate and F1 per τ.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sigmap::eval::ground_truth::voxelise_in;
use sigmap::experiment::run::runner::{ground_truth, observable, registered_placement};
use sigmap::experiment::{simulate, Experiment, SweepValue};
use sigmap::mapping::octree::DEPTH;
use sigmap::mapping::Key;
use sigmap::sim::truth::draw_pose;
use sigmap::uncertainty::UncertainPose;
use std::path::Path;

const THRESHOLDS: [f64; 10] = [0.02, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];

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
    match result {
        Ok(sums) => {
            println!("tau,precision,false_free_rate,f1");
            for (tau, [precision, false_free, f1]) in THRESHOLDS.iter().zip(sums) {
                let n = seeds as f64;
                println!(
                    "{tau},{:.4},{:.4},{:.4}",
                    precision / n,
                    false_free / n,
                    f1 / n
                );
            }
        }
        Err(e) => {
            eprintln!("registration_ceiling: {e}");
            std::process::exit(2);
        }
    }
}

/// Per threshold, the sums over seeds of precision, false-free rate and F1.
fn ceiling(experiment: &Experiment, seeds: u64, draws: usize) -> sigmap::Result<Vec<[f64; 3]>> {
    let mut sums = vec![[0.0; 3]; THRESHOLDS.len()];
    let nominal = experiment.world_from_scene().to_isometry();
    let registration = UncertainPose {
        mean: experiment.world_from_scene(),
        covariance: experiment.profile().world_from_scene,
    };
    for seed in 1..=seeds {
        let run = simulate(experiment, seed, |_| {})?;
        let offset = experiment.map_offset(seed);
        let observable = observable(experiment, &run.truth.scans, &offset);
        let truth = ground_truth(experiment, seed);
        let registered = registered_placement(experiment, &run.truth, &offset);
        // The blur: further registration errors on top of the run's own.
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let blurred: Vec<_> = (0..draws)
            .map(|_| {
                let error = nominal.inverse() * draw_pose(&registration, &mut rng).to_isometry();
                voxelise_in(
                    experiment.scene(),
                    experiment.resolution(),
                    &(registered * error),
                )
            })
            .collect();
        let cells: Vec<(bool, f64)> = observable
            .iter()
            .filter_map(|&code| {
                let key = Key::from_morton(code);
                let truly = truth.query(&key, DEPTH)? >= 0.0;
                let occupied = blurred
                    .iter()
                    .filter(|tree| tree.query(&key, DEPTH).is_some_and(|v| v >= 0.0))
                    .count();
                Some((truly, occupied as f64 / draws as f64))
            })
            .collect();
        for (sum, tau) in sums.iter_mut().zip(THRESHOLDS) {
            let (mut tp, mut fp, mut fn_) = (0.0, 0.0, 0.0);
            for &(truly, belief) in &cells {
                match (truly, belief > tau) {
                    (true, true) => tp += 1.0,
                    (false, true) => fp += 1.0,
                    (true, false) => fn_ += 1.0,
                    (false, false) => {}
                }
            }
            sum[0] += tp / (tp + fp);
            sum[1] += fn_ / (tp + fn_);
            sum[2] += 2.0 * tp / (2.0 * tp + fp + fn_);
        }
    }
    Ok(sums)
}
