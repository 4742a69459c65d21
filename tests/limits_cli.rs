//! Bad and absurd input is refused up front: exit 2, one line that names the
//! file and what is wrong, no panic, no hang, no huge allocation.

mod common;

use common::{portable_quickstart, root, sigmap};
use std::path::{Path, PathBuf};

/// The quickstart experiment with absolute paths, one line replaced.
fn experiment(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let text = portable_quickstart();
    assert!(text.contains(from), "{from}");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    path
}

/// `src` (a repository path, or an absolute one) with each `(from, to)`
/// replaced once, written to `dst`.
fn edited(src: impl AsRef<Path>, dst: &Path, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(root().join(src)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from}");
        text = text.replacen(from, to, 1);
    }
    std::fs::write(dst, text).unwrap();
    dst.to_path_buf()
}

/// The tabletop scene (its mesh by absolute path) with `edits`, at `dst`.
fn tabletop(dst: &Path, mesh: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut all = vec![("meshes/bunny.obj", mesh)];
    all.extend_from_slice(edits);
    edited("scenes/tabletop.toml", dst, &all)
}

/// The quickstart experiment reading `file` instead of the shipped `input`
/// (a repository path).
fn experiment_with(dir: &Path, name: &str, input: &str, file: &Path) -> PathBuf {
    let shipped = root().join(input).display().to_string();
    experiment(dir, name, &shipped, file.to_str().unwrap())
}

/// Runs sigmap and checks: exit 2, one line on stderr naming `names` and
/// saying `says`.
fn refused(args: &[&str], names: &str, says: &str) {
    let out = sigmap(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    assert!(
        stderr.contains(names) && stderr.contains(says),
        "{args:?}: expected '{names}' and '{says}' in: {stderr}"
    );
}

#[test]
fn absurd_sizes_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |path: &Path, says: &str| {
        let out = d.join("out");
        refused(
            &[
                "run",
                path.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            path.file_name().unwrap().to_str().unwrap(),
            says,
        );
    };
    let step = "horizontal_step_deg = 0.5";
    run(
        &experiment(d, "tiny_step", step, "horizontal_step_deg = 1e-300"),
        "beams per viewpoint",
    );
    run(
        &experiment(d, "small_step", step, "horizontal_step_deg = 1e-9"),
        "beams per viewpoint",
    );
    // Surface samples between beams multiply a grid's beams by up to nine:
    // a raster that fits without them (810 081 beams a viewpoint) is refused
    // with them, by the experiment file and by `map --interpolate-beams`.
    let fine = experiment(d, "fine_raster", step, "horizontal_step_deg = 0.005");
    let sampled = edited(
        &fine,
        &d.join("fine_sampled.toml"),
        &[("seed = 1", "seed = 1\ninterpolate_beams = true")],
    );
    run(&sampled, "interpolate_beams: 810081 beams per viewpoint");
    let out = d.join("fine.bt");
    refused(
        &[
            "map",
            fine.to_str().unwrap(),
            "--interpolate-beams",
            "--out",
            out.to_str().unwrap(),
        ],
        "fine_raster.toml",
        "--interpolate-beams: interpolate_beams: 810081 beams",
    );
    assert!(!out.exists());
    // A range the uncertainty-aware maps cannot clear: refused by `run` and
    // by `map` before the simulation (it used to build for ever).
    let far = experiment(d, "far", "max_range = 2.0", "max_range = 1e300");
    run(&far, "max_range = 1e300 m");
    let rays_only = experiment(
        d,
        "rays_only",
        r#"methods = ["blind", "unscented", "ray_update"]"#,
        r#"methods = ["ray_update"]"#,
    );
    // A sigma-point set the scaled transform is not defined for.
    for (table, says) in [
        ("alpha = 0.0", "[unscented] alpha = 0 must be above 0"),
        (
            "alpha = 0.5\nbeta = -1.0",
            "[unscented] beta = -1 must be at least 0",
        ),
        (
            "alpha = 0.5\nkappa = nan",
            "[unscented] kappa = NaN must be at least 0",
        ),
    ] {
        let table = format!("[unscented]\n{table}\n\n[robot]");
        run(&experiment(d, "sigma_set", "[robot]", &table), says);
    }
    let near = experiment(d, "near", "min_range = 0.1", "min_range = 3.0");
    run(&near, "max_range = 2 must exceed min_range = 3");
    let far_rays = edited(
        &rays_only,
        &d.join("far_rays.toml"),
        &[("max_range = 2.0", "max_range = 1e4")],
    );
    let map = |path: &Path, resolution: &str, says: &str| {
        let out = d.join("m.bt");
        let args = [
            "map",
            path.to_str().unwrap(),
            "--method",
            "unscented",
            "--resolution",
            resolution,
            "--out",
            out.to_str().unwrap(),
        ];
        refused(&args, path.file_name().unwrap().to_str().unwrap(), says);
    };
    map(&far_rays, "0.5", "at resolution 0.5 m");
    let mut many = std::fs::read_to_string(experiment(d, "many", "seed = 1", "seed = 1")).unwrap();
    for _ in 0..10_001 {
        many.push_str("\n[[viewpoint]]\njoints = [0.0, -1.2, 1.6, -1.97, -1.5708, 0.0]\n");
    }
    std::fs::write(d.join("many.toml"), many).unwrap();
    run(&d.join("many.toml"), "viewpoints");
    // A million viewpoints (58 MB of TOML) under a 1 GB address-space
    // limit: refused on its size before it is parsed (parsing it took the
    // allocator down).
    let mut huge = std::fs::read_to_string(experiment(d, "huge", "seed = 1", "seed = 1")).unwrap();
    huge.push_str(
        &"\n[[viewpoint]]\njoints = [0.0, -1.2, 1.6, -1.97, -1.5708, 0.0]\n".repeat(1_000_000),
    );
    let huge_path = d.join("huge.toml");
    std::fs::write(&huge_path, huge).unwrap();
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v 1000000; exec '{}' run '{}' --out '{}'",
            env!("CARGO_BIN_EXE_sigmap"),
            huge_path.display(),
            d.join("out").display()
        ))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("huge.toml") && stderr.contains("a TOML input holds at most 4 MB"),
        "{stderr}"
    );
    run(
        &experiment(d, "dup_seeds", "seeds = [1, 2, 3]", "seeds = [1, 2, 1]"),
        "lists 1 more than once",
    );
    run(
        &experiment(
            d,
            "dup_methods",
            r#"methods = ["blind","#,
            r#"methods = ["unscented", "blind","#,
        ),
        "lists unscented more than once",
    );
    let sweep = experiment(d, "dup_sweep", "seed = 1", "seed = 1");
    let mut text = std::fs::read_to_string(&sweep).unwrap();
    text.push_str("\n[[sweep]]\nfield = \"pose_error_scale\"\nvalues = [2, 2.0]\n");
    std::fs::write(&sweep, text).unwrap();
    run(&sweep, "lists the value 2 more than once");
    let sweep = experiment(d, "bad_reference", "seed = 1", "seed = 1");
    let mut text = std::fs::read_to_string(&sweep).unwrap();
    text.push_str("\n[[sweep]]\nfield = \"pose_error_scale\"\nvalues = [0, 2]\nreference = 1\n");
    std::fs::write(&sweep, text).unwrap();
    run(&sweep, "reference = 1 is not one of its values (0, 2)");
    let huge = experiment(d, "huge_scale", "seed = 1", "seed = 1");
    let mut text = std::fs::read_to_string(&huge).unwrap();
    text.push_str("\n[[sweep]]\nfield = \"pose_error_scale\"\nvalues = [1e200]\n");
    std::fs::write(&huge, text).unwrap();
    let o = d.join("o");
    let o = o.to_str().unwrap();
    refused(
        &["run", huge.to_str().unwrap(), "--out", o],
        "collaborative.toml",
        "at pose_error_scale = 1e200",
    );
    // A profile with an absurd sigma.
    let profile = edited(
        "experiments/profiles/collaborative.toml",
        &d.join("p.toml"),
        &[("sigma0 = 0.001", "sigma0 = 1e300")],
    );
    let e = experiment_with(
        d,
        "huge_sigma",
        "experiments/profiles/collaborative.toml",
        &profile,
    );
    refused(
        &["run", e.to_str().unwrap(), "--out", o],
        "p.toml",
        "sigma0 = 1e300 must be between 0 and 1",
    );
    // A workspace the octree cannot hold.
    let bunny = root().join("scenes/meshes/bunny.obj");
    let huge_ws = ("max = [0.4, 0.4, 0.36]", "max = [1e6, 0.4, 0.36]");
    let scene = tabletop(&d.join("scene.toml"), bunny.to_str().unwrap(), &[huge_ws]);
    let e = experiment_with(d, "huge_ws", "scenes/tabletop.toml", &scene);
    refused(
        &["run", e.to_str().unwrap()],
        "scene.toml",
        "the map spans only",
    );
    let wide = ("max = [0.4, 0.4, 0.36]", "max = [10.0, 10.0, 0.36]");
    let wide = tabletop(&d.join("wide.toml"), bunny.to_str().unwrap(), &[wide]);
    let gt = d.join("gt.bt");
    refused(
        &[
            "ground-truth",
            wide.to_str().unwrap(),
            "--resolution",
            "0.001",
            "--out",
            gt.to_str().unwrap(),
        ],
        "wide.toml",
        "has 2.33e8 cells on its boundary alone",
    );
    // The registered truth of `sigmap map` covers the whole workspace too.
    let wide_e = experiment_with(d, "wide_e", "scenes/tabletop.toml", &wide);
    refused(
        &[
            "map",
            wide_e.to_str().unwrap(),
            "--method",
            "registered_truth",
            "--resolution",
            "0.001",
            "--out",
            gt.to_str().unwrap(),
        ],
        "wide.toml",
        "cells on its boundary alone",
    );
    // Beams whose cells the observable mask could not hold: 48 000 beams
    // out to 2 km at 1 cm (the ray update alone, which has no clearing
    // bound of its own).
    let far = portable_quickstart()
        .replace("max_range = 2.0", "max_range = 2000.0")
        .replace(
            r#"methods = ["blind", "unscented", "ray_update"]"#,
            r#"methods = ["ray_update"]"#,
        );
    std::fs::write(d.join("far.toml"), far).unwrap();
    refused(
        &[
            "run",
            d.join("far.toml").to_str().unwrap(),
            "--out",
            d.join("far").to_str().unwrap(),
        ],
        "far.toml",
        "the observable mask sigmap scores over takes at most 5e8",
    );
    // A workspace of more than 2^31 cells (60 m x 60 m x 3 m at 1 cm) is
    // run: its truth is computed where the beams reach, not over all of it.
    let hall = (
        "min = [-0.4, -0.4, -0.04]\nmax = [0.4, 0.4, 0.36]",
        "min = [-30.0, -30.0, -0.04]\nmax = [30.0, 30.0, 3.0]",
    );
    let hall = tabletop(&d.join("wide_hall.toml"), bunny.to_str().unwrap(), &[hall]);
    let e = experiment_with(d, "hall", "scenes/tabletop.toml", &hall);
    let big = d.join("big");
    let run = sigmap(&[
        "run",
        e.to_str().unwrap(),
        "--out",
        big.to_str().unwrap(),
        "-q",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let runs = std::fs::read_to_string(big.join("runs.csv")).unwrap();
    let observable: Vec<u64> = runs
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(4).unwrap().parse().unwrap())
        .collect();
    assert!(observable.iter().all(|&n| n > 50_000), "{runs}");
    // Flags.
    let q = "experiments/quickstart.toml";
    refused(
        &[
            "run",
            q,
            "--threads",
            "5000",
            "--out",
            d.join("o").to_str().unwrap(),
        ],
        "--threads 5000",
        "cores",
    );
    refused(&["run", q, "--seed", "7"], "--seed", "unexpected argument");
    refused(
        &["submit", q, "--tasks", "0"],
        "--tasks",
        "between 1 and 10000 tasks",
    );
}

#[test]
fn bad_files_are_named_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Malformed TOML: one line with the position.
    let bad = d.join("bad.toml");
    std::fs::write(&bad, "name = \"x\"\nseeds = [1\n").unwrap();
    refused(&["run", bad.to_str().unwrap()], "bad.toml", "line 2");
    // A mesh that is a device, not a file.
    #[cfg(unix)]
    {
        let mesh = d.join("zero.obj");
        std::os::unix::fs::symlink("/dev/zero", &mesh).unwrap();
        let scene = tabletop(&d.join("scene.toml"), mesh.to_str().unwrap(), &[]);
        let e = experiment_with(d, "zero", "scenes/tabletop.toml", &scene);
        refused(
            &["run", e.to_str().unwrap()],
            "zero.obj",
            "not a regular file",
        );
    }
    // URDFs: a cycle, and a revolute joint without limits.
    let urdf = std::fs::read_to_string(root().join("robots/ur5.urdf")).unwrap();
    let cycle = edited(
        "robots/ur5.urdf",
        &d.join("cycle.urdf"),
        &[(
            "</robot>",
            "<link name=\"a\"/><link name=\"b\"/>\
             <joint name=\"ab\" type=\"fixed\"><parent link=\"a\"/><child link=\"b\"/></joint>\
             <joint name=\"ba\" type=\"fixed\"><parent link=\"b\"/><child link=\"a\"/></joint></robot>",
        )],
    );
    let e = experiment_with(d, "cycle", "robots/ur5.urdf", &cycle);
    refused(&["run", e.to_str().unwrap()], "cycle.urdf", "cycle");
    let first_limit = urdf.find("<limit").unwrap();
    let end = first_limit + urdf[first_limit..].find("/>").unwrap() + 2;
    let nolimit = edited(
        "robots/ur5.urdf",
        &d.join("nolimit.urdf"),
        &[(&urdf[first_limit..end], "")],
    );
    let e = experiment_with(d, "nolimit", "robots/ur5.urdf", &nolimit);
    refused(
        &["run", e.to_str().unwrap()],
        "nolimit.urdf",
        "shoulder_pan_joint",
    );
}

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
    let out = sigmap(&[
        "map",
        "experiments/quickstart.toml",
        "--method",
        "ray_update",
        "-q",
        "--out",
        m,
    ]);
    assert!(out.status.success());
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
        help.contains("[possible values: blind, jacobian, unscented, correlated, ray_update, ray_update_discrete, registered_truth]")
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
    let missing = experiment(d, "missing_scene", "tabletop.toml", "no_such_scene.toml");
    refused(
        &["run", missing.to_str().unwrap(), "-q"],
        "missing_scene.toml",
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
