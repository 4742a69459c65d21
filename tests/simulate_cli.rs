//! End-to-end runs of `sigmap simulate`: determinism across thread counts,
//! files that read back, and a clear exit-2 error for every kind of bad input.

use std::path::Path;
use std::process::Command;

mod common;

use common::{root, sigmap, simulate_quickstart, tool_ok};

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path
                    .strip_prefix(dir)
                    .unwrap()
                    .to_string_lossy()
                    .into_owned();
                out.push((rel, std::fs::read(&path).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn same_seed_gives_identical_bytes_with_one_and_two_threads() {
    let tmp = tempfile::tempdir().unwrap();
    let one = tmp.path().join("one");
    let two = tmp.path().join("two");
    let other_seed = tmp.path().join("seed2");
    for (dir, threads, seed) in [(&one, "1", "7"), (&two, "2", "7"), (&other_seed, "2", "8")] {
        simulate_quickstart(dir, &["--threads", threads, "--seed", seed]);
    }
    let a = files(&one);
    assert!(
        a.len() >= 6 * 4 + 3,
        "expected per-viewpoint files, got {}",
        a.len()
    );
    assert_eq!(a, files(&two), "thread count changed the output");
    assert_ne!(a, files(&other_seed), "the seed must matter");
}

#[test]
fn ply_cloud_matches_the_csv_points() {
    let tmp = tempfile::tempdir().unwrap();
    simulate_quickstart(tmp.path(), &[]);
    let (origin, points) = sigmap::experiment::read_ply(&tmp.path().join("vp_002.ply")).unwrap();
    let mut reader = csv::Reader::from_path(tmp.path().join("vp_002.csv")).unwrap();
    let headers = reader.headers().unwrap().clone();
    let col = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let (status, sx, sy, sz) = (
        col("status"),
        col("scene_x"),
        col("scene_y"),
        col("scene_z"),
    );
    let csv_points: Vec<[f64; 3]> = reader
        .records()
        .map(|r| r.unwrap())
        .filter(|r| &r[status] == "hit")
        .map(|r| {
            [
                r[sx].parse().unwrap(),
                r[sy].parse().unwrap(),
                r[sz].parse().unwrap(),
            ]
        })
        .collect();
    assert_eq!(points, csv_points);
    assert!(points.len() > 1000);
    // Every measured point lies within the scanner's range of the origin.
    for p in &points {
        let d =
            ((p[0] - origin[0]).powi(2) + (p[1] - origin[1]).powi(2) + (p[2] - origin[2]).powi(2))
                .sqrt();
        assert!(d > 0.05 && d < 2.1, "{d}");
    }
    // The truth is kept apart, one row per beam.
    let truth = std::fs::read_to_string(tmp.path().join("truth/vp_002.csv")).unwrap();
    let beams = std::fs::read_to_string(tmp.path().join("vp_002.csv")).unwrap();
    assert_eq!(truth.lines().count(), beams.lines().count());
    assert!(!beams.contains("true_"));
}

/// Copies the quickstart inputs into a temporary tree, applies `edit` to one
/// of them, runs `simulate`, and returns (exit code, stderr, out dir exists).
fn broken(file: &str, edit: impl Fn(String) -> String) -> (i32, String, bool) {
    edited(&[(file, &edit)])
}

/// [`broken`] with several files edited.
fn edited(edits: &[(&str, &dyn Fn(String) -> String)]) -> (i32, String, bool) {
    let tmp = tempfile::tempdir().unwrap();
    let r = root();
    for dir in ["experiments/profiles", "scenes/meshes", "robots"] {
        std::fs::create_dir_all(tmp.path().join(dir)).unwrap();
    }
    for f in [
        "experiments/quickstart.toml",
        "experiments/profiles/collaborative.toml",
        "scenes/tabletop.toml",
        "scenes/meshes/bunny.obj",
        "robots/ur5.urdf",
    ] {
        let text = std::fs::read_to_string(r.join(f)).unwrap();
        let text = match edits.iter().find(|(file, _)| *file == f) {
            Some((_, edit)) => edit(text),
            None => text,
        };
        std::fs::write(tmp.path().join(f), text).unwrap();
    }
    let out_dir = tmp.path().join("out");
    let out = sigmap(&[
        "simulate",
        tmp.path()
            .join("experiments/quickstart.toml")
            .to_str()
            .unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        out_dir.exists(),
    )
}

fn assert_bad(file: &str, edit: impl Fn(String) -> String, names: &str, says: &str) {
    let (code, stderr, wrote) = broken(file, edit);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains(names),
        "error should name {names}: {stderr}"
    );
    assert!(stderr.contains(says), "error should say {says}: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!wrote, "no results may be written on bad input");
}

#[test]
fn bad_inputs_exit_2_naming_file_and_problem() {
    assert_bad(
        "scenes/tabletop.toml",
        |t| t.replace("meshes/bunny.obj", "meshes/rabbit.obj"),
        "rabbit.obj",
        "not found",
    );
    assert_bad(
        "experiments/quickstart.toml",
        |t| t.replace("seed = 1", "seed = = 1"),
        "quickstart.toml",
        "malformed TOML",
    );
    assert_bad(
        "robots/ur5.urdf",
        |t| t.replace("</robot>", ""),
        "ur5.urdf",
        "malformed URDF",
    );
    assert_bad(
        "experiments/quickstart.toml",
        |t| t.replace("flange_link = \"tool0\"", "flange_link = \"tool9\""),
        "ur5.urdf",
        "unknown link 'tool9'",
    );
    assert_bad(
        "experiments/profiles/collaborative.toml",
        |t| {
            t.replace(
                "sigma = [0.001, 0.001, 0.001,",
                "sigma = [0.001, -0.001, 0.001,",
            )
        },
        "collaborative.toml",
        "negative",
    );
    assert_bad(
        "experiments/profiles/collaborative.toml",
        |t| t.replace("sigma0 = 0.001", "sigma0 = nan"),
        "collaborative.toml",
        "sigma0",
    );
    assert_bad(
        "experiments/profiles/collaborative.toml",
        |t| {
            t.replace(
                "sigma = [0.002, 0.002, 0.002, 0.00349, 0.00349, 0.00349]",
                "covariance = [[1,2,0,0,0,0],[2,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]",
            )
        },
        "collaborative.toml",
        "positive semi-definite",
    );
    assert_bad(
        "experiments/quickstart.toml",
        |t| {
            t.replace(
                "joints = [0.0, -1.2, 1.6, -1.97, -1.5708, 0.0]",
                "joints = [0.0, -1.2, 3.5, -1.97, -1.5708, 0.0]",
            )
        },
        "ur5.urdf",
        "elbow_joint",
    );
    assert_bad(
        "experiments/quickstart.toml",
        |t| t.replace("distance = 0.45", "distance = 2.5"),
        "quickstart.toml",
        "out of reach for robot 'ur5': the sensor would stand 2.628 m from its base",
    );
    // Within the arm's reach, but at its own base: the joints bar it.
    assert_bad(
        "experiments/quickstart.toml",
        |t| {
            t.replacen(
                "look_at = [0.0, 0.05, 0.05]",
                "look_at = [-0.55, 0.0, -0.3]",
                1,
            )
            .replacen("from = [0.0, 0.7, 1.0]", "from = [0.0, 0.0, 1.0]", 1)
            .replacen("distance = 0.45", "distance = 0.3", 1)
        },
        "quickstart.toml",
        "unreachable for robot 'ur5': the sensor would stand 0.000 m from its base",
    );
    // A mesh in millimetres read as metres swallows the arm: the error asks.
    assert_bad(
        "scenes/tabletop.toml",
        |t| {
            t.replace("scale = 0.015 ", "scale = 15.0 ")
                .replace("xyz = [0.0, -0.05, 0.0]", "xyz = [0.0, -0.05, -40.0]")
        },
        "quickstart.toml",
        "is inside object 'bunny' (a mesh",
    );
    assert_bad(
        "experiments/quickstart.toml",
        |t| t.replace("distance = 0.45", "distance = nan"),
        "quickstart.toml",
        "viewpoint 2",
    );
    assert_bad(
        "experiments/quickstart.toml",
        |t| t.replacen("seed = 1", "seed = 1\nbeam_pooling = \"face\"", 1),
        "quickstart.toml",
        "beam_pooling = \"face\": use \"faces\"",
    );
}

#[test]
fn a_mesh_far_larger_than_the_workspace_is_named_in_a_note() {
    // The bunny 130 times its size (31 m across), under the table with
    // its ears in the workspace: it runs, and says what the size suggests.
    let (code, stderr, wrote) = broken("scenes/tabletop.toml", |t| {
        t.replace("scale = 0.015 ", "scale = 2.0 ")
            .replace("xyz = [0.0, -0.05, 0.0]", "xyz = [0.0, -0.05, -19.32]")
    });
    assert_eq!(code, 0, "{stderr}");
    assert!(wrote);
    assert!(
        stderr.contains("note: object 'bunny' of ")
            && stderr.contains("times the workspace's diagonal")
            && stderr.contains("`scale = 0.001`"),
        "{stderr}"
    );
    let (code, stderr, _) = broken("scenes/tabletop.toml", |t| t);
    assert_eq!(code, 0, "{stderr}");
    assert!(!stderr.contains("note: object"), "{stderr}");
}

#[test]
fn an_angle_past_a_full_turn_is_named_in_a_note_as_degrees() {
    let (code, stderr, _) = broken("scenes/tabletop.toml", |t| {
        t.replace(
            "rpy = [1.5707963267948966, 0.0, 0.0]",
            "rpy = [90.0, 0.0, 0.0]",
        )
    });
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("note: object 'bunny' of ")
            && stderr.contains("rpy = [90, 0, 0] turns more than once")
            && stderr.contains("write [1.5708, 0.0000, 0.0000]"),
        "{stderr}"
    );
    // Two full turns (4π), so that the viewpoints stay where they were.
    let (code, stderr, _) = broken("experiments/quickstart.toml", |t| {
        let (robot, scene) = t.split_at(t.find("[world_from_scene]").unwrap());
        format!(
            "{robot}{}",
            scene.replacen(
                "rpy = [0.0, 0.0, 0.0]",
                "rpy = [0.0, 0.0, 12.566370614359172]",
                1
            )
        )
    });
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("quickstart.toml [world_from_scene]: rpy = [0, 0, 12.566370614359172]"),
        "{stderr}"
    );
    assert!(!stderr.contains("[robot]"), "{stderr}");
}

#[test]
fn a_seven_joint_arm_runs_with_one_joint_sigma_for_all() {
    // The UR5 with a seventh joint, a revolute one between its last wrist
    // link and the flange, and a profile that gives one encoder error.
    let seventh = |t: String| {
        t.replacen(
            r#"<joint name="wrist_3_link-tool0_fixed_joint" type="fixed">"#,
            r#"<joint name="flange_joint" type="revolute"><axis xyz="0 0 1"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/>"#,
            1,
        )
    };
    let joints = |t: String| {
        t.replace(
            "joints = [0.0, -1.2, 1.6, -1.97, -1.5708, 0.0]",
            "joints = [0.0, -1.2, 1.6, -1.97, -1.5708, 0.0, 0.3]",
        )
    };
    let one_sigma = |t: String| {
        let at = t.find("joint_sigma = ").unwrap();
        let end = at + t[at..].find('\n').unwrap();
        format!("{}joint_sigma = 0.00052{}", &t[..at], &t[end..])
    };
    let (code, stderr, wrote) = edited(&[
        ("robots/ur5.urdf", &seventh),
        ("experiments/quickstart.toml", &joints),
        ("experiments/profiles/collaborative.toml", &one_sigma),
    ]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        wrote && stderr.contains("simulated 6 viewpoints"),
        "{stderr}"
    );
    // The six-value list the shipped profile gives is refused for it.
    let (code, stderr, _) = edited(&[
        ("robots/ur5.urdf", &seventh),
        ("experiments/quickstart.toml", &joints),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("joint_sigma has 6 values, the arm 'ur5' has 7 joints"),
        "{stderr}"
    );
}

#[test]
fn usage_errors_and_help() {
    let out = sigmap(&["simulate"]);
    assert_eq!(out.status.code(), Some(2));
    let out = sigmap(&["simulate", "does/not/exist.toml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("exist.toml: file not found"));
    for args in [&["--help"][..], &["simulate", "--help"][..]] {
        let out = sigmap(args);
        assert!(out.status.success());
        assert!(String::from_utf8_lossy(&out.stdout).contains("Usage"));
    }
}

/// The PLY opens in an independent reader (Python's `plyfile`, which `.ci/run`
/// installs).
#[test]
#[ignore = "needs python3 with plyfile (pip install plyfile); .ci/run runs it"]
fn ply_reads_in_an_independent_reader() {
    common::require_plyfile();
    let tmp = tempfile::tempdir().unwrap();
    simulate_quickstart(tmp.path(), &[]);
    let ply = tmp.path().join("vp_000.ply");
    let script = "import sys; from plyfile import PlyData\n\
                  v = PlyData.read(sys.argv[1])['vertex']\n\
                  print(len(v), v[0]['red'], v[0]['green'], repr(float(v[1]['x'])))";
    let text = tool_ok(Command::new("python3").args(["-c", script, ply.to_str().unwrap()]));
    let fields: Vec<&str> = text.split_whitespace().collect();
    let (origin, points) = sigmap::experiment::read_ply(&ply).unwrap();
    assert_eq!(fields[0].parse::<usize>().unwrap(), points.len() + 1);
    assert_eq!(
        (fields[1], fields[2]),
        ("255", "0"),
        "vertex 0 is the red sensor origin"
    );
    assert_eq!(fields[3].parse::<f64>().unwrap(), points[0][0]);
    assert!(origin.iter().all(|v| v.is_finite()));
}

/// `--out` never deletes what sigmap did not write: a folder of the user's
/// is refused (exit 2, untouched); a folder sigmap wrote is replaced whole.
#[test]
fn out_never_replaces_a_folder_sigmap_did_not_write() {
    let tmp = tempfile::tempdir().unwrap();
    let mine = tmp.path().join("mine");
    std::fs::create_dir_all(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), "keep me").unwrap();
    let out = common::sigmap(&[
        "simulate",
        "experiments/quickstart.toml",
        "--out",
        mine.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not written by sigmap"));
    assert_eq!(
        std::fs::read_to_string(mine.join("notes.txt")).unwrap(),
        "keep me"
    );
    assert_eq!(std::fs::read_dir(&mine).unwrap().count(), 1);
    // Its own output it replaces, leaving no staging folder beside it.
    let scans = tmp.path().join("scans");
    simulate_quickstart(&scans, &[]);
    simulate_quickstart(&scans, &[]);
    assert!(scans.join("vp_000.csv").exists());
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 2);
}

/// With a frame scale error (`profiles/depth_camera_drift.toml`, 1%),
/// truth/run.toml records each view's drawn scale, and it is the scale the
/// view's ranges were measured with: the median of measured over true range
/// (the depth noise at these depths is a few millimetres a pixel, so over
/// thousands of pixels the median is within 1e-3 of it).
#[test]
fn the_truth_records_each_views_range_scale() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("scans");
    let experiment = root().join("experiments/depth_camera_drift.toml");
    let done = sigmap(&[
        "simulate",
        experiment.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    let run: toml::Table = std::fs::read_to_string(out.join("truth/run.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let column = |file: &Path, name: &str| -> Vec<Option<f64>> {
        let mut reader = csv::Reader::from_path(file).unwrap();
        let at = reader
            .headers()
            .unwrap()
            .iter()
            .position(|h| h == name)
            .unwrap();
        reader
            .records()
            .map(|r| r.unwrap()[at].parse().ok())
            .collect()
    };
    let mut scales = Vec::new();
    for v in 0..6 {
        let scale = run[&format!("viewpoint_{v:03}_range_scale")]
            .as_float()
            .unwrap();
        let measured = column(&out.join(format!("vp_{v:03}.csv")), "range");
        let truth = column(&out.join(format!("truth/vp_{v:03}.csv")), "true_range");
        let mut ratios: Vec<f64> = measured
            .iter()
            .zip(&truth)
            .filter_map(|(m, t)| Some((*m)? / (*t)?))
            .collect();
        assert!(ratios.len() > 5000, "view {v}: {} hits", ratios.len());
        ratios.sort_by(f64::total_cmp);
        let median = ratios[ratios.len() / 2];
        assert!(
            (median - scale).abs() < 1e-3,
            "view {v}: {median} measured, {scale} recorded"
        );
        scales.push(scale);
    }
    assert!(scales.iter().any(|s| (s - 1.0).abs() > 0.005), "{scales:?}");
}
