//! What the maps are told of the errors (`[believed]`, docs/math.md §6.7):
//! the simulator draws the profile's errors whatever the maps are told, so
//! a run told other errors has the same scans, seed by seed, and only the
//! stated covariances and the maps' range model change.

mod common;

use common::{portable_experiment, refused};
use sigmap::experiment::run::runner::run_seed;
use sigmap::experiment::{simulate, Experiment};

/// The quickstart without pooling (so that every point is a raw range with
/// the believed σ), mapped by the Jacobian method and the ray update, with
/// `believed` written into its top-level keys.
fn quickstart(dir: &std::path::Path, believed: &str) -> Experiment {
    let path = portable_experiment(
        "quickstart",
        dir,
        &[(
            "methods = [\"blind\", \"unscented\", \"ray_update\"]",
            &format!(
                "methods = [\"jacobian\", \"ray_update\"]\nbeam_pooling = \"off\"\n{believed}"
            ),
        )],
    );
    Experiment::load(&path).unwrap()
}

/// Told twice every σ, a run has the very scans of the calibrated run,
/// every stated pose covariance four times the drawn one, and every
/// first-order covariance four times the calibrated run's, so its NEES is a
/// quarter of it, point for point. The ray update, which uses no σ, maps
/// the same tree.
#[test]
fn a_run_told_other_errors_has_the_same_scans_and_scaled_covariances() {
    let (calibrated_dir, doubled_dir) =
        (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let calibrated = quickstart(calibrated_dir.path(), "");
    let doubled = quickstart(
        doubled_dir.path(),
        "believed = { sensor_sigma = 2.0, pose_sigma = 2.0 }",
    );
    assert!(calibrated.believed().is_calibrated());
    assert_eq!(doubled.believed().pose_variance(), 4.0);
    let (a, b) = (
        simulate(&calibrated, 3, |_| {}).unwrap(),
        simulate(&doubled, 3, |_| {}).unwrap(),
    );
    for (a, b) in a.scans.iter().zip(&b.scans) {
        let bits = |s: &sigmap::mapping::scan::Scan| {
            s.measurements
                .iter()
                .map(|m| (m.status, m.range.to_bits()))
                .collect::<Vec<_>>()
        };
        assert!(bits(a) == bits(b), "viewpoint {}", a.viewpoint);
        let pairs = [
            (&a.chain.world_from_scene, &b.chain.world_from_scene),
            (&a.chain.world_from_robot, &b.chain.world_from_robot),
            (&a.chain.robot_from_camera, &b.chain.robot_from_camera),
        ];
        for (told, twice) in pairs {
            assert_eq!(told.mean, twice.mean);
            assert!((twice.covariance - told.covariance * 4.0).amax() <= 1e-18);
            assert!(told.covariance.amax() > 0.0);
        }
    }
    let (a, b) = (
        run_seed(&calibrated, 3).unwrap(),
        run_seed(&doubled, 3).unwrap(),
    );
    let row = |outcome: &sigmap::experiment::run::runner::SeedOutcome, method: &str| {
        outcome
            .rows
            .iter()
            .find(|r| r.method == method)
            .unwrap()
            .clone()
    };
    for metric in ["anees", "nees_point"] {
        let (told, twice) = (
            row(&a, "jacobian").get(metric),
            row(&b, "jacobian").get(metric),
        );
        assert!(
            (twice * 4.0 - told).abs() < 1e-9 * told,
            "{metric}: {twice} told twice the sigmas, {told} calibrated"
        );
    }
    for metric in ["false_free_rate", "f1", "brier"] {
        assert_eq!(
            row(&a, "ray_update").get(metric),
            row(&b, "ray_update").get(metric),
            "{metric}"
        );
    }
}

/// A map told less error than there is is over-confident: its NEES is
/// above the calibrated map's. A factor out of bounds is refused, naming the
/// experiment file and the key.
#[test]
fn an_over_confident_map_has_a_larger_nees_and_bad_factors_are_refused() {
    let (calibrated_dir, told_dir) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let calibrated = quickstart(calibrated_dir.path(), "");
    let told_half = quickstart(told_dir.path(), "believed = { pose_sigma = 0.5 }");
    let anees = |e: &Experiment| {
        let outcome = run_seed(e, 2).unwrap();
        outcome
            .rows
            .iter()
            .find(|r| r.method == "jacobian")
            .unwrap()
            .get("anees")
    };
    let (calibrated, over_confident) = (anees(&calibrated), anees(&told_half));
    assert!(
        over_confident > 1.5 * calibrated,
        "{over_confident} against {calibrated}"
    );

    let dir = tempfile::tempdir().unwrap();
    let bad = portable_experiment(
        "quickstart",
        dir.path(),
        &[("seed = 1", "seed = 1\nbelieved = { pose_sigma = -1.0 }")],
    );
    let out = dir.path().join("out");
    refused(
        &[
            "run",
            &bad.display().to_string(),
            "--out",
            &out.display().to_string(),
            "-q",
        ],
        "quickstart.toml",
        "[believed] pose_sigma = -1e0 must be between 0 and 100",
    );
    assert!(!out.exists());
}

/// `sigmap simulate` writes what the maps are told: `scan.toml`'s range
/// model is the believed one, with the `[believed]` factors beside it, and
/// each view's chain file states the believed pose covariances; a
/// calibrated experiment writes no `[believed]` table.
#[test]
fn scan_files_state_the_believed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let files = |believed: &str, name: &str| -> (toml::Table, toml::Table) {
        let sub = dir.path().join(name);
        std::fs::create_dir_all(&sub).unwrap();
        let path = portable_experiment(
            "quickstart",
            &sub,
            &[("seed = 1", &format!("seed = 1\n{believed}"))],
        );
        let out = sub.join("scans");
        common::sigmap_ok(&[
            "simulate",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        let read = |file: &str| -> toml::Table {
            std::fs::read_to_string(out.join(file))
                .unwrap()
                .parse()
                .unwrap()
        };
        (read("scan.toml"), read("vp_000.chain.toml"))
    };
    let (calibrated, calibrated_chain) = files("", "calibrated");
    let (told, told_chain) = files(
        "believed = { sensor_sigma = 0.5, pose_sigma = 2.0 }",
        "told",
    );
    assert!(!calibrated.contains_key("believed"));
    let believed = told["believed"].as_table().expect("a [believed] table");
    assert_eq!(believed["sensor_sigma"].as_float(), Some(0.5));
    assert_eq!(believed["pose_sigma"].as_float(), Some(2.0));
    let sigma0 = |m: &toml::Table| m["range"]["sigma0"].as_float().unwrap();
    assert!((sigma0(&told) - 0.5 * sigma0(&calibrated)).abs() < 1e-15);
    // Every covariance entry of every transform: four times the calibrated.
    let entries = |chain: &toml::Table| -> Vec<f64> {
        chain["transform"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|t| t["covariance"].as_array().unwrap().clone())
            .flat_map(|row| row.as_array().unwrap().clone())
            .map(|v| v.as_float().unwrap())
            .collect()
    };
    let (a, b) = (entries(&calibrated_chain), entries(&told_chain));
    assert_eq!(a.len(), 3 * 36);
    assert!(a.iter().any(|v| *v > 0.0));
    for (a, b) in a.iter().zip(&b) {
        assert!((b - 4.0 * a).abs() <= 1e-12 * a.abs(), "{b} against {a}");
    }
}

/// The results folder's README and report say what the maps were told:
/// the profile's errors, the `[believed]` factors, or that a sweep axis
/// sets them per cell.
#[test]
fn the_results_say_what_the_maps_were_told() {
    use sigmap::experiment::output::{folder_readme::folder_readme, told_errors};
    let dir = tempfile::tempdir().unwrap();
    let shipped =
        |name: &str| Experiment::load(&common::root().join("experiments").join(name)).unwrap();
    let told_half = quickstart(dir.path(), "believed = { pose_sigma = 0.5 }");
    let cases = [
        (
            shipped("quickstart.toml"),
            "the profile's, as the simulator draws them",
        ),
        (told_half, "pose σ × 0.5, range σ × 1 of the profile's"),
        (
            shipped("believed_errors.toml"),
            "; a sweep axis sets them per cell",
        ),
    ];
    for (experiment, says) in cases {
        assert!(
            told_errors(&experiment).contains(says),
            "{}",
            told_errors(&experiment)
        );
        assert!(
            folder_readme(&experiment).contains(says),
            "{}",
            experiment.name()
        );
    }
}
