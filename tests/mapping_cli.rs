//! End-to-end runs of `sigmap map` and `sigmap opdf`.

mod common;

use common::{portable_quickstart, sigmap, sigmap_ok};
use sigmap::geometry::Point3;
use sigmap::mapping::octomap_io::read_octree;
use sigmap::mapping::Clamp;

#[test]
fn maps_are_written_and_carry_free_space_and_surfaces() {
    let dir = tempfile::tempdir().unwrap();
    for method in ["unscented", "ray_update", "blind", "jacobian"] {
        let out = dir.path().join(format!("{method}.ot"));
        let run = sigmap(&[
            "map",
            "experiments/quickstart.toml",
            "--method",
            method,
            "--resolution",
            "0.02",
            "-q",
            "--out",
            out.to_str().unwrap(),
        ]);
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
    assert!(!bad.exists());
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
#[test]
fn score_gives_a_maps_run_row() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = d.join("ray_update.ot");
    let run_dir = d.join("run");
    let text = portable_quickstart()
        .replace("seeds = [1, 2, 3]", "seeds = [1]")
        .replace(
            "methods = [\"blind\", \"unscented\", \"ray_update\"]",
            "methods = [\"ray_update\"]",
        );
    let experiment = d.join("quickstart.toml");
    std::fs::write(&experiment, text).unwrap();
    let e = experiment.to_str().unwrap();
    sigmap_ok(&[
        "map",
        e,
        "--method",
        "ray_update",
        "-q",
        "--out",
        map.to_str().unwrap(),
    ]);
    sigmap_ok(&["run", e, "-q", "--out", run_dir.to_str().unwrap()]);
    let csv = d.join("scores.csv");
    sigmap_ok(&[
        "score",
        map.to_str().unwrap(),
        e,
        "-q",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let coarse = d.join("coarse.ot");
    sigmap_ok(&[
        "map",
        e,
        "--method",
        "ray_update",
        "--resolution",
        "0.02",
        "-q",
        "--out",
        coarse.to_str().unwrap(),
    ]);
    let refused = sigmap(&["score", coarse.to_str().unwrap(), e]);
    let rows = |path: &std::path::Path| -> Vec<Vec<String>> {
        csv::Reader::from_path(path)
            .unwrap()
            .records()
            .map(|r| r.unwrap().iter().map(String::from).collect())
            .collect()
    };
    let (ours, theirs) = (rows(&csv), rows(&run_dir.join("runs.csv")));
    assert_eq!(ours.len(), 1);
    // Every column but the method name and the tree's memory (bytes).
    let n = ours[0].len();
    assert_eq!(ours[0][..2], theirs[0][..2]);
    assert_eq!(ours[0][3..n - 1], theirs[0][3..n - 1]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("resolution is 0.02 m"), "{stderr}");
}

#[test]
fn the_registered_truth_is_mapped_and_scored_as_run_scores_it() {
    // `sigmap map --method registered_truth` writes the reference that `run`
    // scores; recorded scans have no truth to give it.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = portable_quickstart()
        .replace("seeds = [1, 2, 3]", "seeds = [2]")
        .replace(
            "methods = [\"blind\", \"unscented\", \"ray_update\"]",
            "methods = [\"registered_truth\"]",
        );
    let experiment = d.join("quickstart.toml");
    std::fs::write(&experiment, text).unwrap();
    let e = experiment.to_str().unwrap();
    let (map, run_dir, csv) = (d.join("truth.ot"), d.join("run"), d.join("scores.csv"));
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    sigmap_ok(&[
        "map",
        e,
        "--method",
        "registered_truth",
        "--seed",
        "2",
        "-q",
        "--out",
        &path(&map),
    ]);
    sigmap_ok(&["run", e, "-q", "--out", &path(&run_dir)]);
    sigmap_ok(&[
        "score",
        &path(&map),
        e,
        "--seed",
        "2",
        "-q",
        "--csv",
        &path(&csv),
    ]);
    let rows = |path: &std::path::Path| -> Vec<Vec<String>> {
        csv::Reader::from_path(path)
            .unwrap()
            .records()
            .map(|r| r.unwrap().iter().map(String::from).collect())
            .collect()
    };
    let (ours, theirs) = (rows(&csv), rows(&run_dir.join("runs.csv")));
    let n = ours[0].len();
    assert_eq!(ours[0][..2], theirs[0][..2]);
    assert_eq!(ours[0][3..n - 1], theirs[0][3..n - 1]);
    let header = csv::Reader::from_path(run_dir.join("runs.csv"))
        .unwrap()
        .headers()
        .unwrap()
        .clone();
    let column = header.iter().position(|h| h == "precision").unwrap();
    let precision: f64 = theirs[0][column].parse().unwrap();
    assert!(
        precision < 1.0,
        "the registration error costs the truth: {precision}"
    );
    let refused = sigmap(&[
        "map",
        "--scans",
        "no.graph",
        "--profile",
        "experiments/profiles/collaborative_poses.toml",
        "--method",
        "registered_truth",
        "--out",
        &path(&d.join("x.bt")),
    ]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("scoring reference"), "{stderr}");
}
