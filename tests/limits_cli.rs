//! Bad and absurd input is refused up front: exit 2, one line that names the
//! file and what is wrong, no panic, no hang, no huge allocation.

mod common;

use common::{portable_quickstart, refused, root, sigmap};
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

/// `sigmap run PATH` refused: exit 2, one line naming the file and saying
/// `says`.
fn run_refused(d: &Path, path: &Path, says: &str) {
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
}

/// Rasters, ranges and sigma-point sets no map could be built from.
#[test]
fn absurd_rasters_ranges_and_sigma_sets_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let step = "horizontal_step_deg = 0.5";
    run_refused(
        d,
        &experiment(d, "tiny_step", step, "horizontal_step_deg = 1e-300"),
        "beams per viewpoint",
    );
    run_refused(
        d,
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
    run_refused(d, &sampled, "interpolate_beams: 810081 beams per viewpoint");
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
    run_refused(d, &far, "max_range = 1e300 m");
    let rays_only = experiment(
        d,
        "rays_only",
        r#"methods = ["blind", "unscented", "ray_update"]"#,
        r#"methods = ["ray_update"]"#,
    );
    // A sigma-point set the scaled transform is not defined for.
    for (table, says) in [
        (
            "alpha = 0.0",
            "[unscented] alpha = 0 must be at least 0.0001",
        ),
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
        run_refused(d, &experiment(d, "sigma_set", "[robot]", &table), says);
    }
    let near = experiment(d, "near", "min_range = 0.1", "min_range = 3.0");
    run_refused(d, &near, "max_range = 2 must exceed min_range = 3");
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
}

/// Lists too long or repeated, a TOML file too large to parse, sweeps and
/// profiles with values out of range.
#[test]
fn oversized_and_repeated_lists_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut many = std::fs::read_to_string(experiment(d, "many", "seed = 1", "seed = 1")).unwrap();
    for _ in 0..10_001 {
        many.push_str("\n[[viewpoint]]\njoints = [0.0, -1.2, 1.6, -1.97, -1.5708, 0.0]\n");
    }
    std::fs::write(d.join("many.toml"), many).unwrap();
    run_refused(d, &d.join("many.toml"), "viewpoints");
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
    run_refused(
        d,
        &experiment(d, "dup_seeds", "seeds = [1, 2, 3]", "seeds = [1, 2, 1]"),
        "lists 1 more than once",
    );
    run_refused(
        d,
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
    run_refused(d, &sweep, "lists the value 2 more than once");
    let sweep = experiment(d, "bad_reference", "seed = 1", "seed = 1");
    let mut text = std::fs::read_to_string(&sweep).unwrap();
    text.push_str("\n[[sweep]]\nfield = \"pose_error_scale\"\nvalues = [0, 2]\nreference = 1\n");
    std::fs::write(&sweep, text).unwrap();
    run_refused(d, &sweep, "reference = 1 is not one of its values (0, 2)");
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
    // A negative scale error of the frames.
    let profile = edited(
        "experiments/profiles/collaborative.toml",
        &d.join("q.toml"),
        &[("sigma0 = 0.001", "sigma0 = 0.001\nscale_sigma = -0.01")],
    );
    let e = experiment_with(
        d,
        "negative_scale",
        "experiments/profiles/collaborative.toml",
        &profile,
    );
    refused(
        &["run", e.to_str().unwrap(), "--out", o],
        "q.toml",
        "scale_sigma = -1e-2 must be between 0 and 0.1",
    );
}

/// Workspaces whose truth, or whose observable mask, no map could hold.
#[test]
fn workspaces_too_large_to_score_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bunny = root().join("scenes/meshes/bunny.obj");
    // A workspace the octree cannot hold.
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
        "the observable mask sigmap scores over walks at most 5e9",
    );
}

/// A workspace of more than 2^31 cells is not refused.
#[test]
fn a_workspace_of_more_than_2_31_cells_is_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bunny = root().join("scenes/meshes/bunny.obj");
    // 60 m x 60 m x 3 m at 1 cm: its truth is computed where the beams reach, not over all of it.
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
}

/// Flags with values no run could use.
#[test]
fn absurd_flags_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
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
        // A map or a scan graph that is a device is refused, not read
        // until memory runs out (before: `score /dev/zero` read forever).
        let quickstart = root().join("experiments/quickstart.toml");
        refused(
            &["score", "/dev/zero", quickstart.to_str().unwrap()],
            "/dev/zero: the map (first argument)",
            "not a regular file",
        );
        let profile = root().join("experiments/profiles/collaborative_poses.toml");
        let out = d.join("x.ot");
        let scans = [
            "map",
            "--scans",
            "/dev/zero",
            "--profile",
            profile.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        refused(&scans, "/dev/zero", "not a regular file");
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
