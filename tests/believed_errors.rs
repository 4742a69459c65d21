//! What the maps are told of the errors (`[believed]`, docs/math.md §6.7):
//! the simulator draws the profile's errors whatever the maps are told, so
//! a run told other errors has the same scans, seed by seed, and only the
//! stated covariances and the maps' range model change.

mod common;

use common::{portable_experiment, quickstart_run_refused, refused};
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

/// `believed = { profile = ".../experiments/profiles/NAME", ... }` with
/// `extra` keys after the profile.
fn believed_profile(name: &str, extra: &str) -> String {
    let path = common::root().join("experiments/profiles").join(name);
    format!("believed = {{ profile = \"{}\"{extra} }}", path.display())
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
    let (other, _) = files(&believed_profile("industrial.toml", ""), "other");
    assert_eq!(other["believed"]["profile"].as_str(), Some("industrial"));
    assert_eq!(other["range"]["sigma0"].as_float(), Some(0.0001));
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
    let other_dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            shipped("quickstart.toml"),
            "the profile's, as the simulator draws them",
        ),
        (told_half, "pose σ × 0.5, range σ × 1 of the profile's"),
        (
            quickstart(
                other_dir.path(),
                &believed_profile("industrial.toml", ", sensor_sigma = 2.0"),
            ),
            "pose σ × 1, range σ × 2 of those of the profile 'industrial' (the simulator \
             draws those of 'collaborative')",
        ),
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

/// A `[believed] profile` tells the maps another profile's errors on the
/// very scans: each scan states that profile's pose covariances (here the
/// industrial arm's fixed pose-space error where the simulator draws the
/// collaborative arm's joints), at the cell's pose scale and times
/// `pose_sigma²`, and the maps get its range model. Naming the drawn
/// profile itself changes no scan and no score.
#[test]
fn a_believed_profile_is_told_on_the_same_scans() {
    use sigmap::experiment::SweepValue;
    use sigmap::sim::profile::{ArmError, ErrorProfile};
    let dirs: Vec<_> = (0..3).map(|_| tempfile::tempdir().unwrap()).collect();
    let calibrated = quickstart(dirs[0].path(), "");
    let industrial = quickstart(
        dirs[1].path(),
        &believed_profile("industrial.toml", ", pose_sigma = 2.0"),
    );
    let itself = quickstart(dirs[2].path(), &believed_profile("collaborative.toml", ""));
    let told =
        ErrorProfile::load(&common::root().join("experiments/profiles/industrial.toml")).unwrap();
    let ArmError::Pose(told_arm) = told.arm else {
        panic!("the industrial arm's error is a pose error")
    };
    assert_eq!(industrial.believed_profile().name, "industrial");
    assert_eq!(industrial.mapper_view().range, told.range);
    assert_eq!(itself.mapper_view().range, calibrated.mapper_view().range);
    assert!(
        itself.believed().is_calibrated(),
        "the drawn profile named again"
    );

    let runs: Vec<_> = [&calibrated, &industrial, &itself]
        .iter()
        .map(|e| simulate(e, 3, |_| {}).unwrap())
        .collect();
    for (v, scan) in runs[0].scans.iter().enumerate() {
        let (other, same) = (&runs[1].scans[v], &runs[2].scans[v]);
        let bits = |s: &sigmap::mapping::scan::Scan| {
            s.measurements
                .iter()
                .map(|m| (m.status, m.range.to_bits()))
                .collect::<Vec<_>>()
        };
        assert!(
            bits(scan) == bits(other) && bits(scan) == bits(same),
            "viewpoint {v}"
        );
        assert_eq!(scan.chain, same.chain, "viewpoint {v}");
        let stated = [
            (
                &scan.chain.world_from_scene,
                &other.chain.world_from_scene,
                told.world_from_scene,
            ),
            (
                &scan.chain.world_from_robot,
                &other.chain.world_from_robot,
                told_arm,
            ),
            (
                &scan.chain.robot_from_camera,
                &other.chain.robot_from_camera,
                told.robot_from_camera,
            ),
        ];
        for (drawn, stated, believed) in stated {
            assert_eq!(drawn.mean, stated.mean);
            assert_eq!(stated.covariance, believed * 4.0, "viewpoint {v}");
        }
        // The drawn arm error is its joints': a full covariance.
        assert!(scan.chain.world_from_robot.covariance[(0, 1)].abs() > 0.0);
    }
    // The pose scale scales what a calibrated robot believes, too.
    let path = dirs[1].path().join("quickstart.toml");
    let scaled = Experiment::load_cell(
        &path,
        &[("pose_error_scale".into(), SweepValue::Number(3.0))],
    )
    .unwrap();
    let scan = &simulate(&scaled, 3, |_| {}).unwrap().scans[0];
    let expected = told_arm * 9.0 * 4.0;
    assert!((scan.chain.world_from_robot.covariance - expected).amax() <= 1e-15 * expected.amax());

    let (a, b) = (
        run_seed(&calibrated, 3).unwrap(),
        run_seed(&itself, 3).unwrap(),
    );
    assert_eq!(a.rows.len(), b.rows.len());
    for (a, b) in a.rows.iter().zip(&b.rows) {
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
}

/// A believed profile that is missing, that gives a depth camera's error to
/// a laser scanner, or whose joint errors do not fit the arm is refused in
/// one line naming the file; a changed believed profile changes the run's
/// input fingerprint, so that a resume never reuses results told other
/// errors.
#[test]
fn a_believed_profile_is_checked_and_fingerprinted() {
    use sigmap::experiment::study::journal::fingerprint;
    let dir = tempfile::tempdir().unwrap();
    let profiles = common::root().join("experiments/profiles");
    let run_refused = quickstart_run_refused;
    run_refused(
        "believed = { profile = \"nowhere.toml\" }",
        "quickstart.toml",
        "[believed] profile = \"nowhere.toml\": no such file",
    );
    run_refused(
        &believed_profile("depth_camera.toml", ""),
        "quickstart.toml",
        "[believed] profile: the profile",
    );
    let five_joints = dir.path().join("five_joints.toml");
    let text = std::fs::read_to_string(profiles.join("quiet_sensor.toml")).unwrap();
    let edited = text.replace(
        "joint_sigma = [0.00052, 0.00052, 0.00052, 0.00052, 0.00052, 0.00052]",
        "joint_sigma = [0.00052, 0.00052, 0.00052, 0.00052, 0.00052]",
    );
    assert_ne!(edited, text);
    std::fs::write(&five_joints, edited).unwrap();
    run_refused(
        &format!("believed = {{ profile = \"{}\" }}", five_joints.display()),
        "five_joints.toml",
        "joint_sigma has 5 values, the arm 'ur5' has 6 joints",
    );

    let told = dir.path().join("told.toml");
    let industrial = std::fs::read_to_string(profiles.join("industrial.toml")).unwrap();
    std::fs::write(&told, &industrial).unwrap();
    let believed = format!("believed = {{ profile = \"{}\" }}", told.display());
    let sub = tempfile::tempdir_in(dir.path()).unwrap();
    let print = || {
        fingerprint(&[quickstart(sub.path(), &believed)])
            .unwrap()
            .fingerprint
    };
    let before = print();
    assert_eq!(print(), before);
    std::fs::write(
        &told,
        industrial.replace("sigma0 = 0.0001 ", "sigma0 = 0.0002 "),
    )
    .unwrap();
    assert_ne!(print(), before, "the believed profile is an input");
}

/// A sweep's `profile.<path>` values change the drawn profile alone: a
/// believed profile of another file keeps its own value, while naming the
/// drawn profile's file again is the calibrated belief and follows them.
#[test]
fn profile_sweep_values_change_the_drawn_profile_alone() {
    use sigmap::experiment::SweepValue;
    let cell = [
        ("pose_error_scale".to_string(), SweepValue::Number(1.0)),
        (
            "profile.range.sigma0".to_string(),
            SweepValue::Number(0.003),
        ),
    ];
    let shipped = common::root().join("experiments/believed_arm.toml");
    let told = |profile: &str| -> Experiment {
        let cell: Vec<_> = cell
            .iter()
            .cloned()
            .chain([(
                "experiment.believed.profile".to_string(),
                SweepValue::Text(format!("profiles/{profile}")),
            )])
            .collect();
        Experiment::load_cell(&shipped, &cell).unwrap()
    };
    let other = told("collaborative_arm_poses.toml");
    assert_eq!(other.profile().range.sigma0, 0.003);
    assert_eq!(other.believed_profile().range.sigma0, 0.001);
    assert_eq!(other.mapper_view().range.sigma0, 0.001);
    let same = told("collaborative_arm.toml");
    assert!(same.believed().is_calibrated());
    assert_eq!(same.mapper_view().range.sigma0, 0.003);
}
