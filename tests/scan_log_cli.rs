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
