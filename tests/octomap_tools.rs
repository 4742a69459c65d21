//! sigmap's `.bt` / `.ot` files against OctoMap's own tools (Debian's
//! `octomap-tools`, which `.ci/run` installs). Outside CI, without them, the
//! test says so and passes; in CI it must run.

use sigmap::mapping::octomap_io::{is_occupied, read_octree, write_octree};
use sigmap::mapping::octree::{LOG_ODDS_HIT, LOG_ODDS_MISS};
use sigmap::mapping::{Clamp, Key, Octree};
use std::path::Path;
use std::process::Command;

mod common;

/// Runs a command to success and returns what it printed (stdout + stderr).
fn run(command: &mut Command) -> String {
    let out = command.output().expect("run the tool");
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{command:?}: {text}");
    text
}

fn require_tools() {
    assert!(
        Command::new("convert_octree").output().is_ok(),
        "OctoMap's tools not found (apt-get install octomap-tools; `bash .ci/run` does)"
    );
}

/// Free space below, occupied blocks above, a pruned coarse region.
fn tree() -> Octree {
    let mut tree = Octree::new(0.05);
    for x in 0..24u16 {
        for y in 0..24u16 {
            for z in 0..6u16 {
                let delta = if z >= 4 && (x / 4 + y / 4) % 2 == 0 {
                    LOG_ODDS_HIT
                } else {
                    LOG_ODDS_MISS
                };
                tree.update(
                    &Key([32760 + x, 32760 + y, 32766 + z]),
                    delta,
                    Clamp::OCTOMAP,
                );
            }
        }
    }
    tree.update_region(
        &Key([32000, 32000, 32000]),
        12,
        LOG_ODDS_HIT,
        Clamp::OCTOMAP,
    );
    tree
}

#[test]
#[ignore = "needs OctoMap's tools (apt-get install octomap-tools); .ci/run runs it"]
fn octomap_reads_what_sigmap_writes() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let tree = tree();
    let bt = dir.path().join("map.bt");
    let ot = dir.path().join("map.ot");
    write_octree(&bt, &tree, Clamp::OCTOMAP).unwrap();
    write_octree(&ot, &tree, Clamp::OCTOMAP).unwrap();

    // OctoMap converts our .bt into its .ot: reading that back must give the
    // maximum-likelihood tree, leaf for leaf.
    let converted = dir.path().join("converted.ot");
    run(Command::new("convert_octree").arg(&bt).arg(&converted));
    let mut ml = tree.clone();
    ml.map_values(|v| {
        if is_occupied(v) {
            Clamp::OCTOMAP.max
        } else {
            Clamp::OCTOMAP.min
        }
    });
    let back = read_octree(&converted, Clamp::OCTOMAP).unwrap();
    assert_eq!(back, ml);
    assert!(ml.stats().leaves > 100);

    // Our .ot through OctoMap and back: identical, log-odds included.
    let round = dir.path().join("round.ot");
    run(Command::new("convert_octree").arg(&ot).arg(&round));
    assert_eq!(read_octree(&round, Clamp::OCTOMAP).unwrap(), tree);
    assert_eq!(std::fs::read(&round).unwrap(), std::fs::read(&ot).unwrap());

    // compare_octrees on our .ot and OctoMap's copy of it: no difference.
    let text = run(Command::new("compare_octrees").arg(&ot).arg(&round));
    eprintln!("{text}");
    assert!(text.contains("KLD: 0\n"), "{text}");
    // OctoMap's node and expanded-leaf counts match ours.
    let mut finest = 0usize;
    tree.visit_leaves(|leaf| finest += 1usize << (3 * (16 - leaf.depth) as usize));
    assert!(
        text.contains(&format!("Expanded num. leafs: {finest}\n")),
        "{text}"
    );
    assert!(
        text.contains(&format!("Done ({} nodes)", tree.stats().nodes)),
        "{text}"
    );
}

/// `sigmap map` of the quickstart's first run with the ray update at
/// `resolution`, written to `out`, with `extra` arguments.
fn ray_update_map(resolution: &str, out: &std::path::Path, extra: &[&str]) {
    ray_update_map_of(
        Path::new("experiments/quickstart.toml"),
        resolution,
        out,
        extra,
    );
}

/// [`ray_update_map`] of the experiment `file`.
fn ray_update_map_of(file: &Path, resolution: &str, out: &Path, extra: &[&str]) {
    map_of(file, "ray_update", resolution, out, extra);
}

/// `sigmap map` of the experiment `file`'s first run with `method` at
/// `resolution`, written to `out`, with `extra` arguments.
fn map_of(file: &Path, method: &str, resolution: &str, out: &Path, extra: &[&str]) {
    run(Command::new(env!("CARGO_BIN_EXE_sigmap"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("map")
        .arg(file)
        .args(["--method", method])
        .args(["--resolution", resolution, "-q", "--out"])
        .arg(out)
        .args(extra));
}

/// sigmap's ray update against OctoMap's `insertPointCloud` on the same rays:
/// the same tree, node for node (benches/octomap/insert.cpp, built here with
/// g++ against Debian's liboctomap-dev); with beam pooling too, the rays
/// ending at the pooled points; and `ray_update_discrete` against
/// `insertPointCloud(..., discretize = true)`, at 2 and 5 cm.
#[test]
#[ignore = "needs OctoMap's tools (apt-get install octomap-tools); .ci/run runs it"]
fn ray_update_builds_the_same_tree_as_octomap() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let exe = dir.path().join("insert");
    common::build_against_liboctomap("benches/octomap/insert.cpp", &exe);
    // The quickstart as shipped, with pooling off and on, and with a grid
    // offset drawn for its seed: the rays are exported in the map frame the
    // map is built in.
    let shifted = common::portable_experiment(
        "quickstart",
        dir.path(),
        &[("resolution = 0.01", "resolution = 0.01\ngrid_offset = true")],
    );
    let shipped = Path::new("experiments/quickstart.toml");
    let mut trees = Vec::new();
    for (file, pooling) in [
        (shipped, "off"),
        (shipped, "faces"),
        (shifted.as_path(), "off"),
    ] {
        let name = format!("{pooling}_{}", trees.len());
        let rays = dir.path().join(format!("rays_{name}.bin"));
        let ours = dir.path().join(format!("ours_{name}.ot"));
        let export = ["--export-rays", rays.to_str().unwrap()];
        ray_update_map_of(
            file,
            "0.02",
            &ours,
            &[&export[..], &["--beam-pooling", pooling]].concat(),
        );
        let theirs = dir.path().join(format!("octomap_{name}.ot"));
        run(Command::new(&exe).arg(&rays).arg("0.02").arg(&theirs));
        let ours_tree = read_octree(&ours, Clamp::OCTOMAP).unwrap();
        let their_tree = read_octree(&theirs, Clamp::OCTOMAP).unwrap();
        assert_eq!(
            ours_tree.stats().nodes,
            their_tree.stats().nodes,
            "{pooling}"
        );
        assert_eq!(
            ours_tree, their_tree,
            "{pooling}: every leaf and log-odds equal"
        );
        for resolution in ["0.02", "0.05"] {
            // The rays again: a grid offset is drawn in voxels.
            let rays = dir.path().join(format!("rays_discrete_{name}.bin"));
            let ours_discrete = dir.path().join(format!("ours_discrete_{name}.ot"));
            let export = ["--export-rays", rays.to_str().unwrap()];
            let extra = [&export[..], &["--beam-pooling", pooling]].concat();
            map_of(
                file,
                "ray_update_discrete",
                resolution,
                &ours_discrete,
                &extra,
            );
            let theirs_discrete = dir.path().join(format!("octomap_discrete_{name}.ot"));
            run(Command::new(&exe)
                .arg(&rays)
                .arg(resolution)
                .arg(&theirs_discrete)
                .arg("discretize"));
            let ours = read_octree(&ours_discrete, Clamp::OCTOMAP).unwrap();
            let theirs = read_octree(&theirs_discrete, Clamp::OCTOMAP).unwrap();
            assert_eq!(ours, theirs, "{pooling} at {resolution}: discretized");
            if resolution == "0.02" {
                assert!(ours != ours_tree, "one ray per end cell is another map");
            }
        }
        trees.push(ours_tree);
    }
    assert!(trees[0] != trees[1], "pooling moved the rays' ends");
    assert!(trees[0] != trees[2], "the grid offset moved the map");
}

/// Finest cells whose class (occupied, free, unknown) differs between two
/// trees, and the finest cells known in either.
fn class_differences(a: &Octree, b: &Octree) -> (usize, usize) {
    let class = |v: Option<f32>| v.map(is_occupied);
    let (mut differ, mut known) = (0, 0);
    for (x, y, x_first) in [(a, b, true), (b, a, false)] {
        x.visit_leaves(|leaf| {
            let side = 1u32 << (16 - leaf.depth);
            for i in 0..side {
                for j in 0..side {
                    for k in 0..side {
                        let key = Key([
                            leaf.key.0[0] + i as u16,
                            leaf.key.0[1] + j as u16,
                            leaf.key.0[2] + k as u16,
                        ]);
                        let other = y.query(&key, 16);
                        // Cells known in both are counted from `a` only.
                        if !x_first && other.is_some() {
                            continue;
                        }
                        known += 1;
                        if class(Some(leaf.value)) != class(other) {
                            differ += 1;
                        }
                    }
                }
            }
        });
    }
    (differ, known)
}

/// `sigmap score` of two maps against the quickstart's first run (rows
/// appended to `csv`): per metric, the two values.
fn quickstart_scores(
    maps: [&std::path::Path; 2],
    csv: &std::path::Path,
) -> impl Fn(&str) -> (f64, f64) {
    for map in maps {
        run(Command::new(env!("CARGO_BIN_EXE_sigmap"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .arg("score")
            .arg(map)
            .args(["experiments/quickstart.toml", "-q", "--csv"])
            .arg(csv));
    }
    let mut reader = csv::Reader::from_path(csv).unwrap();
    let header = reader.headers().unwrap().clone();
    let rows: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
    move |metric| {
        let i = header.iter().position(|h| h == metric).unwrap();
        (rows[0][i].parse().unwrap(), rows[1][i].parse().unwrap())
    }
}

/// `sigmap export` writes a ScanGraph that OctoMap's own `graph2tree` reads
/// and maps into the tree sigmap's ray update builds from the same scans:
/// node for node at 2 cm and at the quickstart's 1 cm (the ray update
/// keys, cuts and walks OctoMap's `float` rays), and `sigmap score` gives
/// both maps the same scores within 0.001.
#[test]
#[ignore = "needs OctoMap's tools (apt-get install octomap-tools); .ci/run runs it"]
fn graph2tree_maps_the_exported_scans_as_the_ray_update_does() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let export = dir.path().join("export");
    let stdout = run(Command::new(env!("CARGO_BIN_EXE_sigmap"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["export", "experiments/quickstart.toml", "-q", "--out"])
        .arg(&export));
    assert!(stdout.is_empty(), "quiet: {stdout}");
    for file in [
        "scans.graph",
        "poses.txt",
        "README.txt",
        "vp_000.ply",
        "vp_005.ply",
    ] {
        assert!(export.join(file).is_file(), "{file}");
    }
    let poses = std::fs::read_to_string(export.join("poses.txt")).unwrap();
    assert_eq!(poses.lines().filter(|l| !l.starts_with('#')).count(), 6);
    for resolution in ["0.02", "0.01"] {
        let theirs = dir.path().join(format!("octomap_{resolution}.bt"));
        run(Command::new("graph2tree")
            .arg("-i")
            .arg(export.join("scans.graph"))
            .arg("-o")
            .arg(&theirs)
            .args(["-res", resolution, "-m", "2"]));
        let ours = dir.path().join(format!("ours_{resolution}.ot"));
        ray_update_map(resolution, &ours, &[]);
        // graph2tree writes the full tree beside the .bt as <name>.bt.ot.
        let full = dir.path().join(format!("octomap_{resolution}.bt.ot"));
        let their_tree = read_octree(&full, Clamp::OCTOMAP).unwrap();
        let ours_tree = read_octree(&ours, Clamp::OCTOMAP).unwrap();
        let (differ, known) = class_differences(&ours_tree, &their_tree);
        eprintln!("{resolution} m: {differ} of {known} finest cells classed differently");
        assert_eq!(ours_tree, their_tree, "every leaf and log-odds equal");
        if resolution == "0.02" {
            continue;
        }
        assert!(known > 100_000, "{known}");
        assert!(differ * 1000 <= known, "{differ} of {known} differ");
        // At the experiment's resolution, `sigmap score` on OctoMap's map
        // gives sigmap's own ray-update scores within 0.001.
        let score = quickstart_scores([&full, &ours], &dir.path().join("scores.csv"));
        for metric in [
            "precision",
            "recall",
            "f1",
            "false_free_rate",
            "unknown_fraction",
            "brier",
            "roc_auc",
        ] {
            let (theirs, ours) = score(metric);
            eprintln!("{metric}: graph2tree {theirs:.6}, sigmap {ours:.6}");
            assert!(
                (theirs - ours).abs() <= 1e-3,
                "{metric}: {theirs} vs {ours}"
            );
        }
    }
}

/// Writes a ScanGraph's nodes as the plain-text log `log2graph` reads
/// (`sigmap map --scans` reads it too).
fn write_scan_log(graph: &std::path::Path, log: &std::path::Path) {
    use sigmap::mapping::scan_graph::parse_scan_graph;
    let nodes = parse_scan_graph(&std::fs::read(graph).unwrap()).unwrap();
    std::fs::write(log, sigmap::mapping::scan_log::to_scan_log(&nodes)).unwrap();
}

/// `sigmap map --scans` on a graph made by OctoMap's own `log2graph`: with
/// the ray update, the tree agrees with `graph2tree`'s on ≥ 99.9% of the
/// finest cells (both read the same f32 graph; they differ only by f32
/// against f64 arithmetic); an OPDF method maps the same graph, and scores
/// within 0.005 of the OPDF map sigmap builds from its own scans (the
/// recorded graph carries the arm error on the sensor pose, not per joint).
#[test]
#[ignore = "needs OctoMap's tools (apt-get install octomap-tools); .ci/run runs it"]
fn map_scans_agrees_with_graph2tree_on_a_log2graph_graph() {
    require_tools();
    let dir = tempfile::tempdir().unwrap();
    let sigmap = || {
        let mut command = Command::new(env!("CARGO_BIN_EXE_sigmap"));
        command.current_dir(env!("CARGO_MANIFEST_DIR"));
        command
    };
    let export = dir.path().join("export");
    run(sigmap()
        .args(["export", "experiments/quickstart.toml", "-q", "--out"])
        .arg(&export));
    let log = dir.path().join("scans.log");
    write_scan_log(&export.join("scans.graph"), &log);
    let graph = dir.path().join("from_log.graph");
    run(Command::new("log2graph").arg(&log).arg(&graph));
    let theirs = dir.path().join("octomap.bt");
    run(Command::new("graph2tree")
        .arg("-i")
        .arg(&graph)
        .arg("-o")
        .arg(&theirs)
        .args(["-res", "0.01", "-m", "2"]));
    let map_scans_of = |scans: &std::path::Path, method: &str, out: &std::path::Path| {
        run(sigmap()
            .args(["map", "--scans"])
            .arg(scans)
            .args([
                "--profile",
                "experiments/profiles/collaborative_poses.toml",
                "--method",
                method,
                "--resolution",
                "0.01",
                "--max-range",
                "2",
                "-q",
                "--out",
            ])
            .arg(out));
    };
    let map_scans = |method: &str, out: &std::path::Path| map_scans_of(&graph, method, out);
    let ours = dir.path().join("ours.ot");
    map_scans("ray_update", &ours);
    let their_tree = read_octree(&dir.path().join("octomap.bt.ot"), Clamp::OCTOMAP).unwrap();
    let ours_tree = read_octree(&ours, Clamp::OCTOMAP).unwrap();
    let (differ, known) = class_differences(&ours_tree, &their_tree);
    eprintln!("ray update: {differ} of {known} finest cells classed differently");
    assert!(known > 100_000, "{known}");
    assert!(differ * 1000 <= known, "{differ} of {known} differ");
    // The log itself, read by sigmap (poses by the same convention as
    // log2graph's, points kept as f64): the same tree to the same bound.
    let from_log = dir.path().join("from_log.ot");
    map_scans_of(&log, "ray_update", &from_log);
    let log_tree = read_octree(&from_log, Clamp::OCTOMAP).unwrap();
    let (differ, known) = class_differences(&log_tree, &their_tree);
    eprintln!("ray update of the log: {differ} of {known} finest cells classed differently");
    assert!(known > 100_000, "{known}");
    assert!(differ * 1000 <= known, "{differ} of {known} differ");

    // An OPDF method on the same graph, scored against the quickstart's truth
    // (the export is in the run's map frame), beside sigmap's own OPDF map
    // with the settings a recorded graph gets by default (no pooling, no
    // samples, the risk level 0.5).
    let recorded = dir.path().join("recorded_unscented.ot");
    map_scans("unscented", &recorded);
    let simulated = dir.path().join("simulated_unscented.ot");
    run(sigmap()
        .args([
            "map",
            "experiments/quickstart.toml",
            "--method",
            "unscented",
            "--beam-pooling",
            "off",
            "--interpolate-beams",
            "off",
            "-q",
            "--out",
        ])
        .arg(&simulated));
    let score = quickstart_scores([&recorded, &simulated], &dir.path().join("scores.csv"));
    for metric in ["precision", "recall", "f1", "false_free_rate", "brier"] {
        let (recorded, simulated) = score(metric);
        eprintln!("{metric}: recorded graph {recorded:.6}, simulated scans {simulated:.6}");
        assert!(
            (recorded - simulated).abs() <= 5e-3,
            "{metric}: {recorded} vs {simulated}"
        );
    }
}
