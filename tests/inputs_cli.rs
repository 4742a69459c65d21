//! Each command refuses input it cannot use with one line that says what
//! the input is and what is wrong (exit 2): `regress`'s baselines, `export`'s
//! cell, `score`'s CSV, `map --scans`'s graphs and profiles, the flags, and
//! inputs given in the wrong place. The experiment files' own limits are
//! `limits_cli`'s.

mod common;

use common::{portable_experiment, refused, root, sigmap};
use std::path::Path;

#[test]
fn regress_refuses_what_it_cannot_compare() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let baseline = root().join("results/baselines/quickstart.csv");
    let b = baseline.to_str().unwrap();
    let text = std::fs::read_to_string(&baseline).unwrap();
    let header = text.lines().next().unwrap();
    let write = |name: &str, body: &str| {
        let p = d.join(name);
        std::fs::write(&p, body).unwrap();
        p.to_str().unwrap().to_string()
    };
    let empty = write("empty.csv", "");
    let header_only = write("header.csv", &format!("{header}\n"));
    let nan: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("{l}\n")
            } else {
                let mut f: Vec<&str> = l.split(',').collect();
                f[4] = "NaN";
                format!("{}\n", f.join(","))
            }
        })
        .collect();
    let nan = write("nan.csv", &nan);
    let second = text.lines().nth(1).unwrap();
    let dup = write("dup.csv", &format!("{text}{second}\n"));
    for (path, says) in [
        (empty.as_str(), "holds no rows"),
        (header_only.as_str(), "holds no rows"),
        (nan.as_str(), "no finite metric"),
        (dup.as_str(), "twice"),
        (d.to_str().unwrap(), "is not a file"),
    ] {
        refused(&["regress", b, "--baseline", path], path, says);
    }
    refused(
        &["regress", b, "--baseline", b, "--tolerance", "nope=0.1"],
        "nope",
        "no metric",
    );
    // The baseline against itself passes.
    assert!(sigmap(&["regress", b, "--baseline", b]).status.success());
    // A consistency check of a method that propagates nothing, or of none.
    refused(
        &["regress", b, "--consistent", "ray_update"],
        "quickstart.csv",
        "no nees_point of 'ray_update' (the methods that propagate covariances here: blind, \
         unscented)",
    );
    refused(
        &["regress", b],
        "regress",
        "give --baseline BASELINE.csv, --consistent METHOD",
    );
    refused(
        &[
            "regress",
            b,
            "--consistent",
            "unscented",
            "--tolerance",
            "f1=0.1",
        ],
        "--tolerance",
        "needs --baseline",
    );
}

#[test]
fn export_refuses_a_cell_the_experiment_does_not_have() {
    refused(
        &["export", "experiments/quickstart.toml", "--cell", "3"],
        "--cell: sweep cell 3",
        "1 sweep cells",
    );
}

#[test]
fn score_never_rewrites_a_csv_sigmap_did_not_write() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("m.ot");
    let (m, csv) = (map.to_str().unwrap(), dir.path().join("mine.csv"));
    common::quickstart_ray_update_map(&map);
    let score = [
        "score",
        m,
        "experiments/quickstart.toml",
        "-q",
        "--csv",
        csv.to_str().unwrap(),
    ];
    assert!(sigmap(&score).status.success());
    // Someone adds a column of their own: every runs.csv column is still
    // there, but rewriting the file would drop theirs.
    let theirs: String = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .enumerate()
        .map(|(i, l)| format!("{l},{}\n", if i == 0 { "note" } else { "keep me" }))
        .collect();
    std::fs::write(&csv, &theirs).unwrap();
    refused(&score, "mine.csv", "header is not the runs.csv columns");
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), theirs);
}

#[test]
fn map_scans_refuses_bad_graphs_and_profiles() {
    use sigmap::geometry::{Isometry3, Point3, Vector3};
    use sigmap::mapping::scan_graph::{to_scan_graph, ScanNode};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let node = ScanNode {
        pixels: None,
        id: 0,
        map_from_sensor: Isometry3::new(Vector3::new(0.0, 0.0, 1.0), Vector3::new(3.1, 0.0, 0.0)),
        points: (0..50)
            .map(|i| Point3::new(0.01 * i as f64, 0.0, 0.8))
            .collect(),
    };
    let good = to_scan_graph(&[node]);
    let write = |name: &str, bytes: &[u8]| {
        let path = d.join(name);
        std::fs::write(&path, bytes).unwrap();
        path.to_str().unwrap().to_owned()
    };
    let profile = root()
        .join("experiments/profiles/collaborative_poses.toml")
        .display()
        .to_string();
    let out = d.join("map.bt");
    let out = out.to_str().unwrap();
    let map = |graph: &str, profile: &str| -> Vec<String> {
        [
            "map",
            "--scans",
            graph,
            "--profile",
            profile,
            "--out",
            out,
            "-q",
        ]
        .map(String::from)
        .to_vec()
    };
    let refused_map = |graph: &str, profile: &str, names: &str, says: &str| {
        let args = map(graph, profile);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(&args, names, says);
        assert!(!Path::new(out).exists(), "no map written");
    };
    let truncated = write("truncated.graph", &good[..good.len() - 10]);
    refused_map(&truncated, &profile, "truncated.graph", "truncated");
    let mut counts = good.clone();
    counts[4..8].copy_from_slice(&1_000_000u32.to_le_bytes());
    let counts = write("counts.graph", &counts);
    refused_map(&counts, &profile, "counts.graph", "claims 1000000 points");
    // The pose translation's x: after n, count, 50 points and the i32 tag.
    let mut nan = good.clone();
    let at = 4 + 4 + 50 * 28 + 4;
    nan[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    let nan = write("nan.graph", &nan);
    refused_map(&nan, &profile, "nan.graph", "NaN");
    let missing = d.join("missing.graph").display().to_string();
    refused_map(&missing, &profile, "missing.graph", "cannot read");
    // A plain-text scan log: a bad line is named; a log of no points, or
    // text that is no log, is refused.
    let nan = write("nan.log", b"NODE 0 0 1 0 0 0\n0 0 0.8\n0 NaN 0.8\n");
    refused_map(
        &nan,
        &profile,
        "nan.log",
        "line 3: 'NaN' is not a finite number",
    );
    let empty = write("empty.log", b"# scans\nNODE 0 0 1 0 0 0\n");
    refused_map(&empty, &profile, "empty.log", "the scans hold no points");
    let other = write("notes.txt", b"not scans at all\n");
    refused_map(
        &other,
        &profile,
        "notes.txt",
        "not a valid scan log: line 1",
    );
    let blank = write("blank.log", b"");
    refused_map(
        &blank,
        &profile,
        "blank.log",
        "neither a scan log nor a ScanGraph",
    );
    // The collaborative profile gives the arm error per joint.
    let good = write("good.graph", &good);
    let joints = root()
        .join("experiments/profiles/collaborative.toml")
        .display()
        .to_string();
    refused_map(&good, &joints, "collaborative.toml", "joint_sigma");
    refused(
        &["map", "--scans", &good, "--profile", &profile, "-q"],
        "--out",
        "--scans needs --out",
    );
    refused(
        &[
            "map",
            "--scans",
            &good,
            "--profile",
            &profile,
            "--out",
            out,
            "--angular-step",
            "0",
        ],
        "--angular-step",
        "between 0 and 10 degrees",
    );
    refused(
        &[
            "map",
            "experiments/quickstart.toml",
            "--profile",
            &profile,
            "--out",
            out,
        ],
        "--profile",
        "are for --scans",
    );
    // Missing --profile is clap's: exit 2 with its usage text.
    let args = ["map", "--scans", good.as_str(), "--out", out];
    assert_eq!(sigmap(&args).status.code(), Some(2), "{args:?}");
    // And the good graph maps.
    let args = map(&good, &profile);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let ok = sigmap(&args);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(Path::new(out).is_file());
}

/// The command line of a careful tool: the help lists the values a flag
/// takes, `run` offers no flag it would refuse, a bad value gets one line
/// with the possible values, and a negative number reaches the range check.
#[test]
fn the_command_line_lists_values_and_checks_negative_numbers() {
    let help = String::from_utf8_lossy(&sigmap(&["map", "--help"]).stdout).into_owned();
    assert!(
        help.contains("[possible values: blind, jacobian, unscented, correlated, ray_update, ray_update_discrete, registered_truth, consensus_truth, registration_belief]")
            && help.contains("[possible values: off, faces, windows]"),
        "{help}"
    );
    let run_help = String::from_utf8_lossy(&sigmap(&["run", "--help"]).stdout).into_owned();
    assert!(!run_help.contains("--seed"), "{run_help}");
    let q = "experiments/quickstart.toml";
    refused(
        &["map", q, "--method", "bogus"],
        "--method",
        "[possible values: blind,",
    );
    refused(
        &["map", q, "--resolution", "-0.01"],
        "--resolution",
        "resolution = -0.01 must be between 0.001 and 1 m",
    );
}

/// Inputs in the wrong place or missing say what they are: `score`'s
/// arguments swapped, `status` on a results folder that is no submission, a
/// scene file named relative to the experiment that is not there; a `.bt`
/// scored says why its scores differ from the `.ot`'s, and `export` points
/// to the `.ot` graph2tree writes.
#[test]
fn misplaced_and_missing_inputs_say_what_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let q = "experiments/quickstart.toml";
    let out = d.join("q");
    let out_s = out.to_str().unwrap();
    let run = sigmap(&["run", q, "--out", out_s, "-q"]);
    assert!(run.status.success());
    let map = out.join("map_blind.bt");
    refused(
        &["score", q, map.to_str().unwrap()],
        "quickstart.toml",
        "the map (.bt or .ot) comes first",
    );
    refused(
        &["status", out_s],
        "results of `sigmap run`",
        "no submit.toml",
    );
    let missing = portable_experiment("quickstart", d, &[("tabletop.toml", "no_such_scene.toml")]);
    refused(
        &["run", missing.to_str().unwrap(), "-q"],
        missing.to_str().unwrap(),
        "no_such_scene.toml\": no such file (looked for",
    );
    let scored = sigmap(&["score", map.to_str().unwrap(), q]);
    assert!(scored.status.success());
    let note = String::from_utf8_lossy(&scored.stderr);
    assert!(
        note.contains("a .bt holds only occupied and free"),
        "{note}"
    );
    let exported = sigmap(&["export", q, "--out", d.join("e").to_str().unwrap()]);
    let says = String::from_utf8_lossy(&exported.stderr);
    assert!(says.contains("score map.bt.ot"), "{says}");
}

/// A map that is not an octree is named as the map argument.
#[test]
fn a_map_that_is_no_octree_is_named_as_the_map() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("garbage.bt");
    std::fs::write(&bad, "not an octree\n").unwrap();
    refused(
        &[
            "score",
            bad.to_str().unwrap(),
            "experiments/quickstart.toml",
        ],
        "garbage.bt: the map (first argument)",
        "not an OctoMap file",
    );
}
