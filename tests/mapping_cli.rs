//! End-to-end runs of `sigmap map` and `sigmap opdf`.

mod common;

use common::{portable_quickstart, sigmap, sigmap_ok};
use sigmap::geometry::Point3;
use sigmap::mapping::octomap_io::read_octree;
use sigmap::mapping::Clamp;
use std::path::{Path, PathBuf};

/// `sigmap map` of the quickstart with `method` at 2 cm into `out`, plus
/// `extra` arguments.
fn map_quickstart_at_2cm(method: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "map",
        "experiments/quickstart.toml",
        "--method",
        method,
        "--resolution",
        "0.02",
        "-q",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    sigmap(&args)
}

#[test]
fn maps_are_written_and_carry_free_space_and_surfaces() {
    let dir = tempfile::tempdir().unwrap();
    for method in ["unscented", "ray_update", "blind", "jacobian"] {
        let out = dir.path().join(format!("{method}.ot"));
        let run = map_quickstart_at_2cm(method, &out, &[]);
        assert!(
            run.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        let tree = read_octree(&out, Clamp::OCTOMAP).unwrap();
        let at = |x, y, z| tree.value_at(&Point3::new(x, y, z));
        // Open air 25 cm above the table centre, seen by every viewpoint: free.
        assert!(at(0.0, 0.0, 0.3).unwrap() < 0.0, "{method}: free space");
        // The table top (z = 0.003) beside the bunny, seen from above: one of
        // the two cells that straddle it is occupied.
        let top = at(0.1, 0.1, 0.001)
            .unwrap_or(f32::MIN)
            .max(at(0.1, 0.1, -0.001).unwrap_or(f32::MIN));
        assert!(top > 0.0, "{method}: table surface");
        // Inside the table, 5 cm under its top: never observed.
        assert!(at(0.1, 0.1, -0.051).is_none(), "{method}: occluded");
    }
}

#[test]
fn interpolate_beams_adds_surface_to_opdf_maps_only() {
    // Surface samples between beams (docs/math.md §5.4) count as surface
    // evidence in the OPDF maps (more occupied cells); the ray update takes
    // no samples. The flag alone turns them on, `off` off (the default is
    // on: docs/math.md §5.7).
    let dir = tempfile::tempdir().unwrap();
    let build = |method: &str, samples: bool| {
        let out = dir.path().join(format!("{method}_{samples}.ot"));
        let extra: &[&str] = if samples {
            &["--interpolate-beams"]
        } else {
            &["--interpolate-beams", "off"]
        };
        let run = map_quickstart_at_2cm(method, &out, extra);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        read_octree(&out, Clamp::OCTOMAP).unwrap()
    };
    let (plain, sampled) = (build("unscented", false), build("unscented", true));
    let occupied =
        |tree: &sigmap::mapping::Octree| tree.leaves().iter().filter(|l| l.value > 0.0).count();
    assert!(
        occupied(&sampled) > occupied(&plain),
        "{} vs {}",
        occupied(&sampled),
        occupied(&plain)
    );
    let ray = |samples| build("ray_update", samples).leaves();
    assert_eq!(ray(false), ray(true));
}

#[test]
fn five_millimetre_maps() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fine.bt");
    sigmap_ok(&[
        "map",
        "experiments/quickstart.toml",
        "--resolution",
        "0.005",
        "-q",
        "--out",
        out.to_str().unwrap(),
    ]);
    let tree = read_octree(&out, Clamp::OCTOMAP).unwrap();
    assert_eq!(tree.resolution(), 0.005);
    let at = |z| tree.value_at(&Point3::new(0.1, 0.1, z)).unwrap_or(f32::MIN);
    assert!(at(0.0025).max(at(0.0075)) > 0.0, "table top at z = 0.003");
    assert!(at(0.1) < 0.0, "free above it");
}

#[test]
fn bad_map_requests_exit_2() {
    let out = sigmap(&["map", "experiments/quickstart.toml", "--method", "magic"]);
    assert_eq!(out.status.code(), Some(2));
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("map.png");
    let out = sigmap(&[
        "map",
        "experiments/quickstart.toml",
        "--out",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains(".bt or .ot"));
    let out = sigmap(&[
        "map",
        "experiments/quickstart.toml",
        "--beam-pooling",
        "face",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("[possible values: off, faces, windows]"),
        "{stderr}"
    );
    assert!(!bad.exists());
    // --observed bounds a truth reference; a map sees what its scans see.
    let out = sigmap(&["map", "experiments/quickstart.toml", "--observed"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--observed is for the truth references"),
        "{stderr}"
    );
}

#[test]
fn opdf_figures_are_drawn() {
    let dir = tempfile::tempdir().unwrap();
    sigmap_ok(&["opdf", "--out", dir.path().to_str().unwrap()]);
    for f in ["opdf_fig1.svg", "opdf_fig6.svg"] {
        assert!(std::fs::read_to_string(dir.path().join(f))
            .unwrap()
            .starts_with("<svg"));
    }
    // Every curve (a surface measured at 0.5 m): a probability, free in front
    // of the surface, occupied at it, unknown (½) beyond it.
    let mut reader = csv::Reader::from_path(dir.path().join("opdf.csv")).unwrap();
    let mut curves: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for record in reader.records() {
        let r = record.unwrap();
        let (lambda, p): (f64, f64) = (r[2].parse().unwrap(), r[3].parse().unwrap());
        assert!((0.0..=1.0).contains(&p));
        let name = format!("{} {}", &r[0], &r[1]);
        match curves.last_mut() {
            Some((n, points)) if *n == name => points.push((lambda, p)),
            _ => curves.push((name, vec![(lambda, p)])),
        }
    }
    assert_eq!(curves.len(), 7);
    for (name, points) in &curves {
        assert_eq!(points.len(), 2001, "{name}");
        let at = |l: f64| {
            points
                .iter()
                .min_by(|a, b| (a.0 - l).abs().total_cmp(&(b.0 - l).abs()))
                .unwrap()
                .1
        };
        let (peak_at, peak) = points
            .iter()
            .copied()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert!(
            peak > 0.55 && (peak_at - 0.5).abs() < 0.05,
            "{name}: peak {peak} at {peak_at}"
        );
        assert!(
            at(0.3) < 0.45,
            "{name}: free space in front reads {}",
            at(0.3)
        );
        assert!(
            (at(0.6) - 0.5).abs() < 0.01,
            "{name}: beyond the surface reads {}",
            at(0.6)
        );
    }
    // A thickness that is no voxel edge, or a surface no map reaches, is
    // one line and exit 2 (before: a CSV of inf and NaN).
    for (args, says) in [
        (
            ["--range", "1e308"],
            "range 1e308 m lies outside any map of 0.01 m voxels",
        ),
        (["--thickness", "1e-300"], "thickness of 1e-300 m"),
        (["--range", "nan"], "range NaN m"),
    ] {
        let out = sigmap(
            &[
                &["opdf"][..],
                &args,
                &["--out", &path(&dir.path().join("x"))],
            ]
            .concat(),
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(says), "{stderr}");
    }
}

#[test]
fn ground_truth_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("truth.bt");
    sigmap_ok(&[
        "ground-truth",
        "scenes/shelf.toml",
        "--resolution",
        "0.02",
        "--out",
        out.to_str().unwrap(),
    ]);
    let truth = read_octree(&out, Clamp::OCTOMAP).unwrap();
    // A thin board is occupied; the middle of a compartment is free.
    assert_eq!(
        truth.value_at(&Point3::new(0.15, -0.2, 0.3317)),
        Some(Clamp::OCTOMAP.max)
    );
    assert_eq!(
        truth.value_at(&Point3::new(0.15, -0.2, 0.47)),
        Some(Clamp::OCTOMAP.min)
    );
    let bad = sigmap(&["ground-truth", "scenes/shelf.toml", "--out", "truth.txt"]);
    assert_eq!(bad.status.code(), Some(2));
    let missing = sigmap(&[
        "ground-truth",
        "scenes/nope.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(missing.status.code(), Some(2));
}

/// `sigmap score` on sigmap's own ray-update map of the quickstart's first
/// run gives that run's runs.csv row (same truth, mask and metrics); a map
/// at another resolution is refused.
/// A one-seed quickstart with one method in `dir`: `sigmap map` its run,
/// `sigmap run` it and `sigmap score` the map. Returns the experiment file,
/// the score's row and the run's row (as text, by column name).
fn map_run_and_score(dir: &Path, method: &str, seed: u64) -> (PathBuf, Row, Row) {
    let text = portable_quickstart()
        .replace("seeds = [1, 2, 3]", &format!("seeds = [{seed}]"))
        .replace(
            "methods = [\"blind\", \"unscented\", \"ray_update\"]",
            &format!("methods = [\"{method}\"]"),
        );
    let experiment = dir.join("quickstart.toml");
    std::fs::write(&experiment, text).unwrap();
    let (map, run_dir, csv) = (dir.join("map.ot"), dir.join("run"), dir.join("scores.csv"));
    let (e, seed) = (path(&experiment), seed.to_string());
    let map_args = ["map", &e, "--method", method, "--seed", &seed, "-q"];
    sigmap_ok(&[&map_args[..], &["--out", &path(&map)]].concat());
    sigmap_ok(&["run", &e, "-q", "--out", &path(&run_dir)]);
    let score_args = ["score", &path(&map), &e, "--seed", &seed, "-q"];
    sigmap_ok(&[&score_args[..], &["--csv", &path(&csv)]].concat());
    let row = |file: &Path| {
        let mut reader = csv::Reader::from_path(file).unwrap();
        let header = reader.headers().unwrap().clone();
        let rows: Vec<_> = reader.records().map(|r| r.unwrap()).collect();
        assert_eq!(rows.len(), 1, "{}", file.display());
        header
            .iter()
            .map(String::from)
            .zip(rows[0].iter().map(String::from))
            .collect()
    };
    (experiment, row(&csv), row(&run_dir.join("runs.csv")))
}

/// A runs.csv row: (column, value) in file order.
type Row = Vec<(String, String)>;

fn path(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

/// Every column but the method name and the tree's memory (bytes) agrees.
fn assert_same_scores(ours: &Row, theirs: &Row) {
    assert_eq!(ours.len(), theirs.len());
    for (a, b) in ours.iter().zip(theirs) {
        if a.0 != "method" && a.0 != "bytes" {
            assert_eq!(a, b);
        }
    }
}

#[test]
fn score_gives_a_maps_run_row() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (experiment, ours, theirs) = map_run_and_score(d, "ray_update", 1);
    assert_same_scores(&ours, &theirs);
    let coarse = d.join("coarse.ot");
    let e = path(&experiment);
    sigmap_ok(&[
        "map",
        &e,
        "--method",
        "ray_update",
        "--resolution",
        "0.02",
        "-q",
        "--out",
        &path(&coarse),
    ]);
    let refused = sigmap(&["score", &path(&coarse), &e]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("resolution is 0.02 m"), "{stderr}");
}

#[test]
fn the_truth_references_are_mapped_and_scored_as_run_scores_them() {
    // `sigmap map --method registered_truth` (or consensus_truth, or
    // registration_belief: the same draws over the workspace) writes the
    // reference that `run` scores; recorded scans have no truth to give it.
    for method in ["registered_truth", "consensus_truth", "registration_belief"] {
        let dir = tempfile::tempdir().unwrap();
        let (_, ours, theirs) = map_run_and_score(dir.path(), method, 2);
        assert_same_scores(&ours, &theirs);
        let precision: f64 = theirs
            .iter()
            .find(|(c, _)| c == "precision")
            .unwrap()
            .1
            .parse()
            .unwrap();
        assert!(
            precision < 1.0,
            "{method}: the pose errors cost the truth: {precision}"
        );
        let refused = sigmap(&[
            "map",
            "--scans",
            "no.graph",
            "--profile",
            "experiments/profiles/collaborative_poses.toml",
            "--method",
            method,
            "--out",
            &path(&dir.path().join("x.bt")),
        ]);
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert_eq!(refused.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains(&format!("{method} is a scoring reference")),
            "{stderr}"
        );
    }
}

/// `sigmap map --observed` computes a truth reference over the box of
/// cells the scans observe, the map `sigmap run` writes, to the byte; in a
/// workspace wider than the scans reach that is not the whole workspace's.
#[test]
fn a_truth_over_the_observed_cells_is_the_map_run_writes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let r = common::root();
    let scene = std::fs::read_to_string(r.join("scenes/tabletop.toml"))
        .unwrap()
        .replace("meshes/", &format!("{}/scenes/meshes/", r.display()))
        .replace("min = [-0.4, -0.4, -0.04]", "min = [-3.0, -3.0, -0.04]")
        .replace("max = [0.4, 0.4, 0.36]", "max = [3.0, 3.0, 2.5]");
    let scene_path = d.join("wide.toml");
    std::fs::write(&scene_path, scene).unwrap();
    let file = common::portable_experiment(
        "quickstart",
        d,
        &[
            (
                &format!("\"{}/scenes/tabletop.toml\"", r.display()),
                &format!("\"{}\"", scene_path.display()),
            ),
            ("resolution = 0.01", "resolution = 0.02"),
            ("seeds = [1, 2, 3]", "seeds = [2]"),
            (
                "methods = [\"blind\", \"unscented\", \"ray_update\"]",
                "methods = [\"registered_truth\"]",
            ),
        ],
    );
    let results = d.join("results");
    common::ok(common::run_into(&file, &results, &[]));
    let map = |extra: &[&str]| {
        let out = d.join(format!("truth{}.bt", extra.len()));
        let e = file.to_str().unwrap();
        let args = [
            "map",
            e,
            "--method",
            "registered_truth",
            "--seed",
            "2",
            "-q",
        ];
        sigmap_ok(&[&args[..], extra, &["--out", out.to_str().unwrap()]].concat());
        std::fs::read(out).unwrap()
    };
    let written = std::fs::read(results.join("map_registered_truth.bt")).unwrap();
    assert!(map(&["--observed"]) == written, "not the map run wrote");
    assert!(
        map(&[]) != written,
        "the whole workspace is not the observed box"
    );
}

/// `sigmap map --method M` of an experiment that pairs against further
/// references (`also_paired`, as every paper experiment lists the
/// registered truth) maps M as the experiment without them does, M one of
/// those references included; a file whose `also_paired` repeats its own
/// reference is still refused.
#[test]
fn a_method_the_experiment_also_pairs_against_is_mapped() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, extra: &str| {
        let file = dir.path().join(name);
        let text = portable_quickstart().replace(
            "seeds = [1, 2, 3]",
            &format!("seeds = [1]\nreference = \"ray_update\"\n{extra}"),
        );
        std::fs::write(&file, text).unwrap();
        path(&file)
    };
    let plain = write("plain.toml", "");
    let pairing = write(
        "pairing.toml",
        "also_paired = [\"registered_truth\", \"unscented\"]",
    );
    for method in ["registered_truth", "unscented", "blind"] {
        let map = |experiment: &str, name: &str| {
            let out = path(&dir.path().join(format!("{name}_{method}.ot")));
            let args = ["map", experiment, "--method", method, "--seed", "1", "-q"];
            sigmap_ok(&[&args[..], &["--resolution", "0.02", "--out", &out]].concat());
            std::fs::read(out).unwrap()
        };
        assert!(
            map(&pairing, "pairing") == map(&plain, "plain"),
            "{method}: the same map"
        );
    }
    let repeats = write("repeats.toml", "also_paired = [\"ray_update\"]");
    let out = path(&dir.path().join("x.ot"));
    let refused = sigmap(&["map", &repeats, "--method", "ray_update", "--out", &out]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("repeats.toml")
            && stderr.contains("also_paired lists ray_update, which is already the reference"),
        "{stderr}"
    );
}

#[test]
fn score_against_a_scene_with_recorded_scans() {
    // The quickstart's first run exported as recorded scans, sigmap's ray
    // update of it, scored against the tabletop scene with the scans' mask:
    // close to the run's row. The mask follows the believed poses and the
    // measured ranges, not the true ones, so under the collaborative
    // profile's pose error it differs by a few percent (at zero error it is
    // the run's mask exactly: experiment::scoring's tests).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (experiment, _, theirs) = map_run_and_score(d, "ray_update", 1);
    let e = path(&experiment);
    let export = d.join("export");
    sigmap_ok(&["export", &e, "--seed", "1", "-q", "--out", &path(&export)]);
    let graph = path(&export.join("scans.graph"));
    let scene = path(&common::root().join("scenes/tabletop.toml"));
    let csv = d.join("scene.csv");
    let map = path(&d.join("map.ot"));
    let csv_path = path(&csv);
    // `sigmap score` of the map against the scene, the row appended to `csv`.
    let head = [
        "score",
        &map,
        "--scene",
        &scene,
        "--scans",
        &graph,
        "--max-range",
        "2.0",
    ];
    let score_scene =
        |extra: &[&str]| sigmap_ok(&[&head[..], extra, &["--csv", &csv_path]].concat());
    let shown = score_scene(&[]);
    assert!(shown.contains("against scene"), "{shown}");
    assert!(
        shown.contains("% of ") && shown.contains("returns meet it within 0.02 m"),
        "{shown}"
    );
    let mut reader = csv::Reader::from_path(&csv).unwrap();
    let header = reader.headers().unwrap().clone();
    let row = reader.records().next().unwrap().unwrap();
    let value = |row: &[(String, String)], name: &str| -> f64 {
        row.iter()
            .find(|(c, _)| c == name)
            .unwrap()
            .1
            .parse()
            .unwrap()
    };
    let ours: Row = header
        .iter()
        .map(String::from)
        .zip(row.iter().map(String::from))
        .collect();
    for metric in ["precision", "recall", "f1", "false_free_rate", "brier"] {
        let (a, b) = (value(&ours, metric), value(&theirs, metric));
        assert!((a - b).abs() < 0.05, "{metric}: {a} against the run's {b}");
    }
    let cells = (
        value(&ours, "observable_cells"),
        value(&theirs, "observable_cells"),
    );
    assert!((cells.0 / cells.1 - 1.0).abs() < 0.05, "{cells:?}");
    // The scene moved 5 cm in the map frame: the map no longer fits it.
    let moved = score_scene(&["--scene-pose", "0.05,0,0,0,0,0"]);
    assert!(moved.contains("f1"), "{moved}");
    let rows: Vec<csv::StringRecord> = csv::Reader::from_path(&csv)
        .unwrap()
        .records()
        .map(|r| r.unwrap())
        .collect();
    let f1 = header.iter().position(|c| c == "f1").unwrap();
    let (placed, shifted): (f64, f64) =
        (rows[0][f1].parse().unwrap(), rows[1][f1].parse().unwrap());
    assert!(shifted < placed - 0.2, "{shifted} vs {placed}");
    // The scans' rays meet the scene in place at their returns: no warning.
    // Raised 5 cm, its table top stands in their way: a warning beside the
    // scores.
    let warned = |pose: &str| {
        let out = sigmap(&[&head[..], &["--scene-pose", pose]].concat());
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        stderr
    };
    let in_place = warned("0,0,0,0,0,0");
    assert!(!in_place.contains("warning"), "{in_place}");
    let raised = warned("0,0,0.05,0,0,0");
    assert!(
        raised.contains("warning: only") && raised.contains("check --scene-pose"),
        "{raised}"
    );
    // The note moves it back down: the pose it gives draws no warning and
    // no further move, and lies within a few millimetres of where the
    // scene stood (the scans' registration error).
    let suggested = |stderr: &str| -> Vec<f64> {
        stderr
            .split("give --scene-pose ")
            .nth(1)
            .and_then(|rest| rest.split_whitespace().next())
            .unwrap_or_else(|| panic!("no suggested pose: {stderr}"))
            .split(',')
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let pose = suggested(&raised);
    assert!(pose[2].abs() < 0.01, "{pose:?}");
    let text = |pose: &[f64]| {
        pose.iter()
            .map(f64::to_string)
            .collect::<Vec<_>>()
            .join(",")
    };
    let back = warned(&text(&pose));
    assert!(
        !back.contains("warning") && !back.contains("note"),
        "{back}"
    );
    // Turned 0.1 rad about z, the note turns it back, to the same pose.
    let turned = suggested(&warned("0,0,0,0,0,0.1"));
    assert!(turned[5].abs() < 0.01, "{turned:?}");
    let apart = pose.iter().zip(&turned).map(|(a, b)| (a - b).abs());
    assert!(
        apart.fold(0.0, f64::max) < 1e-3,
        "{pose:?} against {turned:?}"
    );
    // Bad input: one line, exit 2.
    for (args, says) in [
        (vec!["--scene-pose", "1,2,3"], "six finite numbers"),
        (vec!["--max-range", "-1"], "--max-range -1"),
        // A scene placed where no ray goes, or rays cut shorter than a
        // cell: every score would be 0/0.
        (
            vec!["--scene-pose", "5,0,0,0,0,0"],
            "tabletop.toml: none of the",
        ),
        (
            vec!["--max-range", "1e-9"],
            "cells the recorded rays cross (cut at --max-range 0.000000001) lies",
        ),
    ] {
        let out = sigmap(
            &[
                &["score", &map, "--scene", &scene, "--scans", &graph][..],
                &args,
            ]
            .concat(),
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(says), "{stderr}");
    }
    let missing = path(&d.join("nope.graph"));
    let out = sigmap(&["score", &map, "--scene", &scene, "--scans", &missing]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("nope.graph") && stderr.lines().count() == 1,
        "{stderr}"
    );
    let out = sigmap(&["score", &map, "--scene", &scene]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn map_of_a_cell_and_seed_is_the_map_run_writes_for_them_in_its_grid_offset_frame() {
    // The quickstart with a grid offset drawn per seed and a sweep whose
    // first cell (scale 0) differs from the base (scale 1): `sigmap run`
    // writes the map of its first run (cell 0, seed 2); `sigmap map --cell 0
    // --seed 2` must write the same file, in the same (offset) map frame.
    let dir = tempfile::tempdir().unwrap();
    let file = common::portable_experiment(
        "quickstart",
        dir.path(),
        &[
            ("resolution = 0.01", "resolution = 0.02\ngrid_offset = true"),
            ("seeds = [1, 2, 3]", "seeds = [2]"),
            (
                "methods = [\"blind\", \"unscented\", \"ray_update\"]",
                "methods = [\"unscented\", \"ray_update\"]\n\n[[sweep]]\nfield = \"pose_error_scale\"\nvalues = [0.0, 1.0]",
            ),
        ],
    );
    let results = dir.path().join("results");
    common::ok(common::run_into(&file, &results, &[]));
    for method in ["unscented", "ray_update"] {
        let map = |extra: &[&str]| {
            let out = dir.path().join(format!("{method}{}.bt", extra.len()));
            let mut args = vec![
                "map",
                file.to_str().unwrap(),
                "--method",
                method,
                "--seed",
                "2",
                "-q",
                "--out",
                out.to_str().unwrap(),
            ];
            args.extend_from_slice(extra);
            sigmap_ok(&args);
            std::fs::read(out).unwrap()
        };
        let written = std::fs::read(results.join(format!("map_{method}.bt"))).unwrap();
        assert!(
            map(&["--cell", "0"]) == written,
            "{method}: not the run's map"
        );
        assert!(map(&[]) != written, "{method}: the base is not cell 0");
    }
    // Without --cell, a sweep's map says which experiment it is of.
    let out = dir.path().join("base.bt");
    let base = sigmap(&[
        "map",
        file.to_str().unwrap(),
        "--resolution",
        "0.05",
        "--out",
        out.to_str().unwrap(),
    ]);
    let note = String::from_utf8_lossy(&base.stderr);
    assert!(
        base.status.success() && note.contains("sweeps 2 cells") && note.contains("--cell K"),
        "{note}"
    );
    let out = sigmap(&["map", file.to_str().unwrap(), "--cell", "2"]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{message}");
    assert!(
        message.contains("--cell: ") && message.contains("0 to 1"),
        "{message}"
    );
}

#[test]
fn a_malformed_file_is_blamed_on_the_file_not_on_a_flag_given_beside_it() {
    // TOML's "unknown field" error lists every field, `interpolate_beams`
    // and `risk` among them: it must not be reported as the flags' fault.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("typo.toml");
    let text = std::fs::read_to_string(common::root().join("experiments/quickstart.toml")).unwrap();
    std::fs::write(&path, format!("pose_error_scal = 1.0\n{text}")).unwrap();
    let out = sigmap(&[
        "map",
        path.to_str().unwrap(),
        "--interpolate-beams",
        "off",
        "--risk",
        "off",
        "--out",
        dir.path().join("m.bt").to_str().unwrap(),
    ]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{message}");
    assert!(
        message.contains("typo.toml")
            && message.contains("pose_error_scal")
            && !message.contains("--interpolate-beams:")
            && !message.contains("--risk:")
            && message.lines().count() == 1,
        "{message}"
    );
}

#[test]
fn risk_defaults_to_one_half_and_may_be_set_or_turned_off() {
    // The quickstart leaves `risk` to the default, 0.5 (docs/math.md §5.7):
    // `--risk 0.5` gives the same file, `--risk off` another, and a level
    // out of range is refused naming the flag.
    let dir = tempfile::tempdir().unwrap();
    let build = |name: &str, extra: &[&str]| {
        let out = dir.path().join(format!("{name}.ot"));
        let run = map_quickstart_at_2cm("unscented", &out, extra);
        (run, out)
    };
    let (default, default_map) = build("default", &[]);
    let (half, half_map) = build("half", &["--risk", "0.5"]);
    let (off, off_map) = build("off", &["--risk", "off"]);
    assert!(default.status.success() && half.status.success() && off.status.success());
    let bytes = |p: &Path| std::fs::read(p).unwrap();
    assert_eq!(bytes(&default_map), bytes(&half_map));
    assert_ne!(bytes(&default_map), bytes(&off_map));
    let (bad, _) = build("bad", &["--risk", "0.7"]);
    let message = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(2), "{message}");
    assert!(
        message.contains("--risk: ") && message.contains("risk = 0.7"),
        "{message}"
    );
}
