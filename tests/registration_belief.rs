//! The reference `registration_belief` (docs/math.md §7.5): the registered
//! truth blurred over the registration's told covariance, called at a
//! threshold, run and swept like any method.

mod common;

use common::{portable_experiment, quickstart_run_refused, sigmap_ok};
use std::collections::HashMap;

/// The quickstart's seeds with the registered truth and the belief, the
/// belief's threshold swept.
fn belief_sweep(dir: &std::path::Path) -> std::path::PathBuf {
    portable_experiment(
        "quickstart",
        dir,
        &[(
            "methods = [\"blind\", \"unscented\", \"ray_update\"]",
            "methods = [\"registered_truth\", \"registration_belief\"]\n\
                 reference = \"registered_truth\"\n\
                 registration_belief = { threshold = 0.5, draws = 16 }\n\
                 [[sweep]]\n\
                 field = \"experiment.registration_belief.threshold\"\n\
                 values = [0.2, 0.8]",
        )],
    )
}

#[test]
fn a_lower_threshold_calls_more_cells_occupied_from_the_same_draws() {
    // Both cells draw the same registration errors for a seed (one stream
    // per run), so the cells occupied at 0.8 are occupied at 0.2: recall
    // and the false-free rate are ordered seed by seed, and the paired
    // comparison against the registered truth is written for the belief.
    let dir = tempfile::tempdir().unwrap();
    let path = belief_sweep(dir.path());
    let out = dir.path().join("out");
    sigmap_ok(&[
        "run",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    let mut reader = csv::Reader::from_path(out.join("runs.csv")).unwrap();
    let header = reader.headers().unwrap().clone();
    let column = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (cell, seed, method) = (column("cell"), column("seed"), column("method"));
    let (recall, false_free) = (column("recall"), column("false_free_rate"));
    let mut belief: HashMap<(String, String), (f64, f64)> = HashMap::new();
    for row in reader.records().map(|r| r.unwrap()) {
        if &row[method] == "registration_belief" {
            let value = |i: usize| row[i].parse::<f64>().unwrap();
            let threshold = row[cell].rsplit('=').next().unwrap().to_string();
            belief.insert(
                (threshold, row[seed].to_string()),
                (value(recall), value(false_free)),
            );
        }
    }
    assert_eq!(belief.len(), 6, "{belief:?}");
    let mut strictly = 0;
    for s in ["1", "2", "3"] {
        let low = belief[&("0.2".to_string(), s.to_string())];
        let high = belief[&("0.8".to_string(), s.to_string())];
        assert!(
            low.0 >= high.0 && low.1 <= high.1,
            "seed {s}: {low:?} {high:?}"
        );
        strictly += usize::from(low.1 < high.1);
    }
    assert!(strictly >= 2, "the blur matters: {belief:?}");
    let paired = std::fs::read_to_string(out.join("paired.csv")).unwrap();
    assert!(
        paired
            .lines()
            .any(|l| l.contains("registration_belief") && l.contains("registered_truth")),
        "{paired}"
    );
}

#[test]
fn bad_belief_settings_are_refused_with_the_file_named() {
    for (setting, says) in [
        (
            "{ threshold = 1.5 }",
            "[registration_belief] threshold = 1.5",
        ),
        ("{ draws = 0 }", "[registration_belief] draws = 0"),
        ("{ draws = 100000 }", "[registration_belief] draws = 100000"),
        ("{ tau = 0.5 }", "unknown field `tau`"),
    ] {
        quickstart_run_refused(
            &format!("registration_belief = {setting}"),
            "quickstart.toml",
            says,
        );
    }
}
