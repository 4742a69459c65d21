//! Recorded scans as a plain-text log (`NODE x y z roll pitch yaw`, then
//! `x y z` lines: what OctoMap's `log2graph` reads), given to `map --scans`
//! and `score --scans` in place of a ScanGraph: the same scans give the
//! same maps and the same scores.

mod common;

use common::{root, sigmap_ok};
use sigmap::mapping::scan_graph::parse_scan_graph;
use sigmap::mapping::scan_log::to_scan_log;

#[test]
fn a_scan_log_maps_and_scores_as_the_graph_of_the_same_scans() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = |p: &std::path::Path| p.display().to_string();
    let quickstart = path(&root().join("experiments/quickstart.toml"));
    let export = d.join("export");
    sigmap_ok(&["export", &quickstart, "-q", "--out", &path(&export)]);
    let graph = export.join("scans.graph");
    let nodes = parse_scan_graph(&std::fs::read(&graph).unwrap()).unwrap();
    let log = d.join("scans.txt");
    std::fs::write(&log, to_scan_log(&nodes)).unwrap();
    let profile = path(&root().join("experiments/profiles/collaborative_poses.toml"));
    for method in ["ray_update", "unscented"] {
        let map = |scans: &std::path::Path, label: &str| {
            let out = d.join(format!("{method}_{label}.ot"));
            sigmap_ok(&[
                "map",
                "--scans",
                &path(scans),
                "--profile",
                &profile,
                "--method",
                method,
                "--resolution",
                "0.01",
                "--max-range",
                "2",
                "-q",
                "--out",
                &path(&out),
            ]);
            std::fs::read(out).unwrap()
        };
        let (from_graph, from_log) = (map(&graph, "graph"), map(&log, "log"));
        assert!(from_graph.len() > 100_000, "{}", from_graph.len());
        assert!(from_graph == from_log, "{method}: the maps differ");
    }
    let scene = path(&root().join("scenes/tabletop.toml"));
    let map = path(&d.join("unscented_graph.ot"));
    let score = |scans: &std::path::Path| {
        sigmap_ok(&[
            "score",
            &map,
            "--scene",
            &scene,
            "--scans",
            &path(scans),
            "--max-range",
            "2",
        ])
        .lines()
        .skip(1)
        .collect::<Vec<_>>()
        .join("\n")
    };
    let (by_graph, by_log) = (score(&graph), score(&log));
    assert!(by_graph.contains("f1"), "{by_graph}");
    assert_eq!(by_graph, by_log);
}

/// A depth camera's error (`[range] along = "depth"`) holds for beams
/// within 85° of its optical axis: a recorded cloud with a point beside the
/// camera is refused by the maps that use the error, with the point's beam,
/// and mapped by the ray update, which does not.
#[test]
fn a_depth_cameras_error_refuses_a_point_beside_the_camera() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = |p: &std::path::Path| p.display().to_string();
    let mut log = String::from("NODE 0 0 0 0 0 0\n");
    for i in 0..21 {
        for j in 0..21 {
            let (x, y) = (0.03 * (i as f64 - 10.0), 0.03 * (j as f64 - 10.0));
            log.push_str(&format!("{x} {y} 1\n"));
        }
    }
    log.push_str("1 0 0.02\n");
    let scans = d.join("scans.txt");
    std::fs::write(&scans, log).unwrap();
    // The recorded poses' profile with the depth camera's range error.
    let poses = root().join("experiments/profiles/collaborative_poses.toml");
    let poses = std::fs::read_to_string(poses).unwrap();
    let profile = d.join("depth_poses.toml");
    std::fs::write(
        &profile,
        poses.replace("k = 0.002 ", "k2 = 0.0036\nalong = \"depth\"\n"),
    )
    .unwrap();
    let profile = path(&profile);
    let args = |method: &'static str, out: &str| {
        [
            "map",
            "--scans",
            &path(&scans),
            "--profile",
            &profile,
            "--method",
            method,
            "--resolution",
            "0.02",
            "--max-range",
            "2",
            "-q",
            "--out",
            out,
        ]
        .map(str::to_string)
    };
    let out = path(&d.join("map.ot"));
    let refused_args = args("unscented", &out);
    let refused_args: Vec<&str> = refused_args.iter().map(String::as_str).collect();
    common::refused(
        &refused_args,
        "method unscented, scan 0: beam 441",
        "points 88.9 deg off the optical axis (+z), and [range] along = \"depth\"",
    );
    assert!(!d.join("map.ot").exists());
    let ray = args("ray_update", &out);
    sigmap_ok(&ray.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(d.join("map.ot").exists());
}
