//! The simulated depth camera (`[sensor] model = "pinhole"`,
//! `experiments/depth_camera.toml`): its beams pool with their neighbours on
//! the image's pixels, its runs map and score like the laser's, and a
//! mapper of depth images joins its sweep.

mod common;

use common::{portable_experiment, sigmap_ok};
use sigmap::experiment::run::runner::run_seed;
use sigmap::experiment::{simulate, Experiment, SweepValue};
use sigmap::mapping::measured::measured_ranges;
use sigmap::mapping::scan::{BeamStatus, Layouts};
use std::path::Path;

/// The shipped experiment at `pose_error_scale`.
fn depth_camera(scale: f64) -> Experiment {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/depth_camera.toml");
    let cell = [("pose_error_scale".to_string(), SweepValue::Number(scale))];
    Experiment::load_cell(&path, &cell).unwrap()
}

/// With the experiment's defaults (pooled windows), most hits of the
/// camera's views are pooled with the pixels around them, and their pooled
/// ranges lie nearer the true surface than the measured ones (a 3 × 3
/// window averages nine ranges: a third of the error on a plane).
#[test]
fn a_depth_camera_pools_each_pixel_with_its_neighbours() {
    let experiment = depth_camera(1.0);
    let run = simulate(&experiment, 1, |_| {}).unwrap();
    let view = experiment.mapper_view();
    let Layouts::Shared(layout) = view.layouts else {
        panic!("a simulated sensor's layout is shared by its views");
    };
    assert!(layout.pixels.is_some(), "pooled on the pixels");
    let (mut raw, mut pooled, mut count, mut hits) = (0.0, 0.0, 0, 0);
    for (scan, truth) in run.scans.iter().zip(&run.truth.scans) {
        let ranges = measured_ranges(&view, layout, scan).unwrap();
        for ((measured, beam), range) in scan.measurements.iter().zip(&truth.beams).zip(&ranges) {
            if measured.status != BeamStatus::Hit {
                continue;
            }
            hits += 1;
            let Some(range) = range.filter(|r| r.normal.is_some()) else {
                continue;
            };
            raw += (measured.range - beam.range).powi(2);
            pooled += (range.range - beam.range).powi(2);
            count += 1;
        }
    }
    assert!(count * 10 > hits * 7, "{count} of {hits} pooled");
    let (raw, pooled) = ((raw / count as f64).sqrt(), (pooled / count as f64).sqrt());
    assert!(pooled < 0.5 * raw, "pooled rms {pooled} against raw {raw}");
}

/// A run of the shipped experiment at zero pose error: the uncertainty-aware
/// map of the camera's views is near the truth, at least as complete as
/// OctoMap's ray update on the same pixels, and calls fewer of the occupied
/// cells free.
#[test]
fn a_depth_camera_run_maps_the_workcell() {
    let outcome = run_seed(&depth_camera(0.0), 1).unwrap();
    let row = |method: &str| {
        outcome
            .rows
            .iter()
            .find(|r| r.method == method)
            .unwrap_or_else(|| panic!("no {method} row"))
    };
    let (unscented, ray) = (row("unscented"), row("ray_update"));
    let f1 = unscented.get("f1");
    assert!(
        f1 > 0.9 && f1 >= ray.get("f1"),
        "F1 {f1}, ray update {}",
        ray.get("f1")
    );
    let false_free = unscented.get("false_free_rate");
    assert!(
        false_free < ray.get("false_free_rate"),
        "false-free {false_free}, ray update {}",
        ray.get("false_free_rate")
    );
}

/// A `[[mapper]]` that reads depth images (sigmap's own `map --scans` on
/// the run's exported TUM RGB-D folder, given by `{depth}`, `{intrinsics}`
/// and `{depth_scale}`) is run and scored beside sigmap's methods, on the
/// same observable cells.
#[test]
fn a_mapper_of_depth_images_joins_the_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let profile = common::root().join("experiments/profiles/depth_camera_poses.toml");
    let mapper = format!(
        r#"
[[mapper]]
name = "depth_folder"
command = ["{sigmap}", "map", "--scans", "{{depth}}", "--trajectory", "{{poses}}", "--intrinsics", "{{intrinsics}}", "--depth-scale", "{{depth_scale}}", "--resolution", "{{resolution}}", "--beam-pooling", "windows", "--profile", "{profile}", "--out", "{{dir}}/map.ot", "--quiet"]
map = "{{dir}}/map.ot"
"#,
        sigmap = env!("CARGO_BIN_EXE_sigmap"),
        profile = profile.display()
    );
    let experiment = portable_experiment(
        "depth_camera",
        dir.path(),
        &[
            ("seeds = \"1..40\"", "seeds = [1]"),
            (
                "methods = [\"unscented\", \"blind\", \"ray_update\", \"registered_truth\"]",
                "methods = [\"unscented\"]",
            ),
            ("reference = \"ray_update\"", "reference = \"unscented\""),
            ("also_paired = [\"registered_truth\"]", ""),
            ("values = [0.0, 1.0]", "values = [0.0]"),
        ],
    );
    let text = std::fs::read_to_string(&experiment).unwrap();
    std::fs::write(&experiment, text + &mapper).unwrap();
    let out = dir.path().join("out");
    let experiment = experiment.to_str().unwrap();
    sigmap_ok(&["run", experiment, "--out", out.to_str().unwrap(), "--quiet"]);
    let runs = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    let row = |method: &str| -> Vec<String> {
        let line = runs
            .lines()
            .find(|l| l.split(',').nth(2) == Some(method))
            .unwrap_or_else(|| panic!("no {method} row in {runs}"));
        line.split(',').map(String::from).collect()
    };
    let header: Vec<&str> = runs.lines().next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (ours, theirs) = (row("unscented"), row("depth_folder"));
    let observable = column("observable_cells");
    assert_eq!(
        ours[observable], theirs[observable],
        "the same scored cells"
    );
    let recall: f64 = theirs[column("recall")].parse().unwrap();
    assert!(
        recall > 0.9,
        "the images' map finds the surfaces: recall {recall}"
    );
}

/// `sigmap simulate` of a depth camera writes its intrinsics into
/// `scan.toml`, and they give every beam of the scan files its direction.
#[test]
fn a_depth_cameras_scan_files_carry_its_intrinsics() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scans");
    let experiment = common::root().join("experiments/depth_camera.toml");
    sigmap_ok(&[
        "simulate",
        experiment.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let manifest: toml::Table = std::fs::read_to_string(out.join("scan.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let pinhole = manifest["pinhole"].as_table().expect("a [pinhole] table");
    let number = |key: &str| pinhole[key].as_float().unwrap();
    let (fx, fy, cx, cy) = (number("fx"), number("fy"), number("cx"), number("cy"));
    let beams = std::fs::read_to_string(out.join("vp_000.csv")).unwrap();
    let mut rows = 0;
    for line in beams.lines().skip(1) {
        let fields: Vec<f64> = line
            .split(',')
            .take(6)
            .map(|f| f.parse().unwrap())
            .collect();
        let (row, column) = (fields[1], fields[2]);
        let ray = [(column - cx) / fx, (row - cy) / fy, 1.0];
        let norm = ray.iter().map(|v| v * v).sum::<f64>().sqrt();
        for (d, r) in fields[3..6].iter().zip(ray) {
            assert!((d - r / norm).abs() < 1e-12, "{line}");
        }
        rows += 1;
    }
    assert_eq!(rows, 212 * 120);
}
