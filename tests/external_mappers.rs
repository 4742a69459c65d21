//! External mappers in a sweep (`[[mapper]]`): another program maps each
//! run's exported scans and its rows join runs.csv, summary.csv, paired.csv
//! and report.html; every way a mapper can fail is one line and exit 2, with
//! the finished runs kept; OctoMap's own graph2tree and the Python example
//! mapper run end to end.

mod common;

use common::{
    kill_once_journaled, ok, portable_experiment, portable_quickstart, root, run_args, run_into,
    sigmap,
};
use std::collections::BTreeMap;
use std::path::Path;

/// An experiment of the quickstart at 2 cm, `seeds`, `methods` and the
/// mapper table `mapper`, written into `dir`.
fn experiment(dir: &Path, seeds: &str, methods: &str, mapper: &str) -> std::path::PathBuf {
    let text = portable_quickstart()
        .replace("resolution = 0.01", "resolution = 0.02")
        .replace("seeds = [1, 2, 3]", &format!("seeds = {seeds}"))
        .replace(
            "methods = [\"blind\", \"unscented\", \"ray_update\"]",
            &format!("methods = {methods}\n\n{mapper}\n"),
        );
    let path = dir.join("e.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// A TOML array of strings.
fn array(items: &[&str]) -> String {
    let quoted: Vec<String> = items.iter().map(|s| format!("{s:?}")).collect();
    format!("[{}]", quoted.join(", "))
}

/// sigmap's own recorded-scan map builder as an external mapper: the ray
/// update of the exported ScanGraph, written as `.ot`.
fn sigmap_mapper(name: &str) -> String {
    let profile = root().join("experiments/profiles/collaborative_poses.toml");
    let command = array(&[
        env!("CARGO_BIN_EXE_sigmap"),
        "map",
        "--scans",
        "{scans}",
        "--profile",
        profile.to_str().unwrap(),
        "--method",
        "ray_update",
        "--resolution",
        "{resolution}",
        "--max-range",
        "{max_range}",
        "--out",
        "{dir}/map.ot",
        "-q",
    ]);
    format!("[[mapper]]\nname = \"{name}\"\ncommand = {command}\nmap = \"{{dir}}/map.ot\"\n")
}

/// Asserts that the file at `path` has a line holding `needle`.
fn has_row(path: &Path, needle: &str) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(
        text.lines().any(|l| l.contains(needle)),
        "{needle} in {text}"
    );
}

/// Whether paired.csv has a row of `method` against `reference` on `metric`.
fn has_paired(path: &Path, method: &str, reference: &str, metric: &str) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(
        text.lines().any(|l| {
            let r: Vec<&str> = l.split(',').collect();
            r.len() > 4 && (r[1], r[2], r[4]) == (method, reference, metric)
        }),
        "{method} against {reference} on {metric} in {text}"
    );
}

/// `(cell, seed, method) -> metric -> value` of a runs.csv.
fn runs(path: &Path) -> BTreeMap<(String, String, String), BTreeMap<String, f64>> {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    let mut out = BTreeMap::new();
    for record in reader.records() {
        let record = record.unwrap();
        let field = |name: &str| record[header.iter().position(|h| h == name).unwrap()].to_string();
        let values = header
            .iter()
            .zip(record.iter())
            .filter_map(|(h, v)| v.parse::<f64>().ok().map(|v| (h.clone(), v)))
            .collect();
        out.insert((field("cell"), field("seed"), field("method")), values);
    }
    out
}

/// Every classification and probability metric of `method`'s rows equals
/// the ray update's within `tolerance`, seed by seed.
fn rows_match_the_ray_update(out: &Path, method: &str, tolerance: f64) {
    let rows = runs(&out.join("runs.csv"));
    let mut compared = 0;
    for ((cell, seed, m), theirs) in &rows {
        if m != method {
            continue;
        }
        let ours = &rows[&(cell.clone(), seed.clone(), "ray_update".to_string())];
        for metric in [
            "precision",
            "recall",
            "f1",
            "false_free_rate",
            "unknown_fraction",
            "brier",
            "roc_auc",
        ] {
            let (a, b) = (theirs[metric], ours[metric]);
            assert!(
                (a - b).abs() <= tolerance,
                "cell {cell} seed {seed} {metric}: {method} {a}, ray_update {b}"
            );
        }
        compared += 1;
    }
    assert!(compared >= 2, "{compared} rows of {method}");
}

#[test]
fn a_mapper_joins_the_sweep_like_sigmaps_own_methods() {
    let dir = tempfile::tempdir().unwrap();
    let file = experiment(
        dir.path(),
        "[1, 2]",
        "[\"ray_update\"]",
        &sigmap_mapper("recorded"),
    );
    // Leftovers of a killed sigmap (a process that cannot run) are removed
    // when mappers next run; a failed run's folder (marked) is kept.
    let tmp = std::env::temp_dir();
    let (left, failed) = (
        tmp.join("sigmap-mapper-4999999-77"),
        tmp.join("sigmap-mapper-4999999-78"),
    );
    let foreign = tmp.join("sigmap-mapper-4999999-79");
    for folder in [&left, &failed, &foreign] {
        std::fs::create_dir_all(folder.join("work")).unwrap();
    }
    for folder in [&left, &failed] {
        std::fs::write(folder.join(".sigmap-output"), "written by sigmap\n").unwrap();
    }
    std::fs::write(failed.join("FAILED.txt"), "the command failed\n").unwrap();
    let out = dir.path().join("out");
    ok(run_into(&file, &out, &[]));
    assert!(!left.exists(), "a killed run's leftover is removed");
    assert!(failed.exists(), "a failed run's folder is kept");
    assert!(
        foreign.exists(),
        "a folder sigmap did not mark is not sigmap's"
    );
    std::fs::remove_dir_all(&failed).unwrap();
    std::fs::remove_dir_all(&foreign).unwrap();
    // The same scans through the export (f32 points) and sigmap's recorded
    // ray update: the ray update's rows.
    rows_match_the_ray_update(&out, "recorded", 1e-3);
    has_row(&out.join("summary.csv"), ",recorded,f1,");
    has_paired(&out.join("paired.csv"), "recorded", "ray_update", "f1");
    has_row(&out.join("report.html"), "recorded");
    assert!(out.join("map_recorded.bt").is_file());
    // The command it runs is printed before the first run and recorded in
    // run.toml.
    let command = format!(
        "{} map --scans {{scans}} --profile",
        env!("CARGO_BIN_EXE_sigmap")
    );
    let manifest: toml::Table = std::fs::read_to_string(out.join("run.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let recorded = manifest["mappers"]["recorded"].as_str().unwrap();
    assert!(recorded.starts_with(&command), "{recorded}");
    let loud = sigmap(&[
        "run",
        file.to_str().unwrap(),
        "--out",
        dir.path().join("loud").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&loud.stderr);
    let announced = format!("mapper recorded will run for each cell and seed: {recorded}");
    assert!(stderr.starts_with(&announced), "{stderr}");
    // A resume reuses the finished runs; a changed mapper is new input.
    let again = run_into(&file, &out, &[]);
    assert!(again.status.success());
    let changed = std::fs::read_to_string(&file)
        .unwrap()
        .replace("\"-q\"]", "\"--quiet\"]");
    std::fs::write(&file, changed).unwrap();
    let stale = run_into(&file, &out, &[]);
    assert_eq!(stale.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&stale.stderr).contains("other inputs"));
}

/// A script the mapper's command names is part of the inputs: rebuilt (its
/// bytes changed, the experiment file not), a resume refuses the results
/// and names it.
#[test]
fn a_rebuilt_mapper_script_is_new_input() {
    let dir = tempfile::tempdir().unwrap();
    let profile = root().join("experiments/profiles/collaborative_poses.toml");
    let script = dir.path().join("map.sh");
    let body = format!(
        "exec {} map --scans \"$1\" --profile {} --method ray_update --resolution \"$2\" \
         --max-range \"$3\" --out map.ot -q\n",
        env!("CARGO_BIN_EXE_sigmap"),
        profile.display()
    );
    std::fs::write(&script, &body).unwrap();
    let mapper = format!(
        "[[mapper]]\nname = \"script\"\ncommand = {}\nmap = \"map.ot\"\n",
        array(&["sh", "map.sh", "{scans}", "{resolution}", "{max_range}"])
    );
    let file = experiment(dir.path(), "[1]", "[\"ray_update\"]", &mapper);
    let out = dir.path().join("out");
    ok(run_into(&file, &out, &[]));
    std::fs::write(&script, format!("# rebuilt\n{body}")).unwrap();
    let stale = run_into(&file, &out, &[]);
    let err = String::from_utf8_lossy(&stale.stderr);
    assert_eq!(stale.status.code(), Some(2), "{err}");
    assert!(
        err.contains("other inputs") && err.contains("map.sh"),
        "{err}"
    );
}

/// Each way a mapper fails: exit 2, one line naming the mapper, the seed
/// and what happened (with its stderr's end), and seed 1's finished run
/// kept in the journal.
#[test]
fn a_failing_mapper_is_one_line_and_the_finished_runs_stay() {
    let sigmap_bin = env!("CARGO_BIN_EXE_sigmap");
    let profile = root().join("experiments/profiles/collaborative_poses.toml");
    let good = ray_update_line();
    // Seed 1 maps; seed 2 fails as each case says.
    let cases = [
        (
            "echo mapper blew up >&2; exit 1",
            "the command failed (exit status: 1)",
            "mapper blew up",
        ),
        (
            "sleep 30 & echo $! > ${CHILD}; wait",
            "after its timeout of 2 s",
            "",
        ),
        ("true", "wrote no map", ""),
        (
            "echo not an octree > map.ot",
            "not an octree sigmap reads",
            "",
        ),
        (
            "exec ${SIGMAP} map --scans {scans} --profile ${PROFILE} --method ray_update \
             --resolution 0.04 --max-range {max_range} --out {dir}/map.ot -q",
            "resolution 0.04 m",
            "",
        ),
    ];
    let children = tempfile::tempdir().unwrap();
    let child_pid = children.path().join("child.pid");
    for (fails, says, stderr) in cases {
        let fails = fails
            .replace("${SIGMAP}", sigmap_bin)
            .replace("${PROFILE}", profile.to_str().unwrap())
            .replace("${CHILD}", child_pid.to_str().unwrap());
        let script = format!("if [ {{seed}} = 1 ]; then exec {good}; fi; {fails}");
        let mapper = format!(
            "[[mapper]]\nname = \"flaky\"\ncommand = {}\nmap = \"{{dir}}/map.ot\"\ntimeout_s = 2\n",
            array(&["sh", "-c", &script])
        );
        let dir = tempfile::tempdir().unwrap();
        let file = experiment(dir.path(), "[1, 2]", "[\"ray_update\"]", &mapper);
        let out = dir.path().join("out");
        // The failed run's folder, kept for the user, in the test's own
        // temporary folder (removed with it), not the system's.
        let tmp = dir.path().join("tmp");
        std::fs::create_dir(&tmp).unwrap();
        let run = std::process::Command::new(sigmap_bin)
            .args(run_args(&file, &out, &["--threads", "1"]))
            .current_dir(root())
            .env("TMPDIR", &tmp)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{says}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
        assert!(
            err.contains("mapper flaky (seed 2)") && err.contains(says) && err.contains(stderr),
            "{says}: {err}"
        );
        let journal = std::fs::read_to_string(out.join("runs.journal.csv")).unwrap();
        assert!(
            journal.lines().any(|l| l.contains(",1,flaky,")),
            "seed 1 kept: {journal}"
        );
    }
    // What the timed-out command started was stopped with it (its process
    // group): the background `sleep 30` is gone, not sleeping on.
    assert!(!running(&child_pid));
}

/// A shell line that maps `{scans}` into `{dir}/map.ot` with sigmap's ray
/// update at `{resolution}`: a mapper that succeeds.
fn ray_update_line() -> String {
    let profile = root().join("experiments/profiles/collaborative_poses.toml");
    format!(
        "{} map --scans {{scans}} --profile {} --method ray_update --resolution \
         {{resolution}} --max-range {{max_range}} --out {{dir}}/map.ot -q",
        env!("CARGO_BIN_EXE_sigmap"),
        profile.display()
    )
}

/// Whether the process whose id the file at `pid_file` holds still runs
/// (gone, or a zombie waiting for init, is not running).
fn running(pid_file: &Path) -> bool {
    let pid = std::fs::read_to_string(pid_file).unwrap();
    let stat = std::fs::read_to_string(format!("/proc/{}/stat", pid.trim())).unwrap_or_default();
    let state = stat
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .next();
    !matches!(state, None | Some("Z"))
}

/// A mapper runs in a process group of its own, which the terminal's Ctrl-C
/// and a batch system's SIGTERM to sigmap do not reach: sigmap stops it
/// itself. What a mapper leaves running after it exits is stopped too.
#[test]
fn a_mapper_does_not_outlive_its_run_or_a_signal_that_stops_sigmap() {
    let sigmap_bin = env!("CARGO_BIN_EXE_sigmap");
    let dir = tempfile::tempdir().unwrap();
    let pids = |name: &str| dir.path().join(name);
    let run_with = |script: &str| {
        let mapper = format!(
            "[[mapper]]\nname = \"lingers\"\ncommand = {}\nmap = \"{{dir}}/map.ot\"\ntimeout_s = 120\n",
            array(&["sh", "-c", script])
        );
        let file = experiment(dir.path(), "[1]", "[\"ray_update\"]", &mapper);
        std::process::Command::new(sigmap_bin)
            .args(run_args(&file, &dir.path().join("out"), &["--fresh"]))
            .current_dir(root())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    // A mapper that maps, leaving a `sleep` behind: gone when its run ends.
    let left = pids("left.pid");
    let maps = format!(
        "sleep 60 & echo $! > {}; exec {}",
        left.display(),
        ray_update_line()
    );
    let finished = run_with(&maps).wait_with_output().unwrap();
    assert!(
        finished.status.success(),
        "{}",
        String::from_utf8_lossy(&finished.stderr)
    );
    assert!(!running(&left), "the mapper's leftover sleeps on");
    // A mapper still at work when sigmap is stopped by SIGTERM.
    let working = pids("working.pid");
    let mut run = run_with(&format!("echo $$ > {}; exec sleep 60", working.display()));
    let start = std::time::Instant::now();
    while !working.exists() || std::fs::read_to_string(&working).unwrap().trim().is_empty() {
        assert!(start.elapsed().as_secs() < 60, "the mapper never started");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let pid = libc::pid_t::try_from(run.id()).unwrap();
    // SAFETY: kill(2) on the sigmap child this test started.
    unsafe {
        libc::kill(pid, libc::SIGTERM);
    }
    let status = run.wait().unwrap();
    assert!(!status.success());
    let stopped = std::time::Instant::now();
    while running(&working) {
        assert!(
            stopped.elapsed().as_secs() < 5,
            "the mapper sleeps on after sigmap was stopped"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// A map in another frame (here, every point 5 m away: a mapper that did
/// not keep the export's map frame) is refused.
#[test]
fn a_map_in_another_frame_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let far = dir.path().join("far.ot");
    let mut tree = sigmap::mapping::Octree::new(0.02);
    for i in 0..50 {
        let p = sigmap::geometry::Point3::new(5.0 + 0.02 * i as f64, 5.0, 5.0);
        tree.update(&tree.key(&p).unwrap(), 1.0, sigmap::mapping::Clamp::OCTOMAP);
    }
    sigmap::mapping::octomap_io::write_octree(&far, &tree, sigmap::mapping::Clamp::OCTOMAP)
        .unwrap();
    let mapper = format!(
        "[[mapper]]\nname = \"elsewhere\"\ncommand = {}\nmap = \"map.ot\"\n",
        array(&["cp", far.to_str().unwrap(), "map.ot"])
    );
    let file = experiment(dir.path(), "[1]", "[\"ray_update\"]", &mapper);
    let out = dir.path().join("out");
    let run = run_into(&file, &out, &[]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{err}");
    assert!(
        err.contains("mapper elsewhere") && err.contains("not in the map frame"),
        "{err}"
    );
}

/// The shipped experiment with fewer cells and seeds, its paths absolute.
fn small_octomap_compare(dir: &Path) -> std::path::PathBuf {
    portable_experiment(
        "octomap_compare",
        dir,
        &[
            ("seeds = \"1..5\"", "seeds = [1, 2]"),
            ("values = [0.0, 1.0, 2.0, 4.0, 8.0]", "values = [0.0, 8.0]"),
        ],
    )
}

/// OctoMap's graph2tree in a sweep: its rows equal the ray update's within
/// OctoMap's f32 points (scores within 0.001, as tests/octomap_tools.rs
/// finds for one map), and a run killed mid-way and resumed writes the
/// files of an uninterrupted one byte for byte.
#[test]
#[ignore = "needs OctoMap's tools (apt-get install octomap-tools); .ci/run runs it"]
fn graph2tree_joins_the_sweep_and_a_killed_run_resumes_identically() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_octomap_compare(dir.path());
    let whole = dir.path().join("whole");
    ok(run_into(&file, &whole, &[]));
    rows_match_the_ray_update(&whole, "octomap", 1e-3);
    has_paired(&whole.join("paired.csv"), "ray_update", "octomap", "f1");
    has_row(&whole.join("summary.csv"), ",octomap,f1,");
    assert!(std::fs::read_to_string(whole.join("report.html"))
        .unwrap()
        .contains("octomap"));
    // Killed once the first run is journaled, then resumed.
    let killed = dir.path().join("killed");
    kill_once_journaled(
        &[
            "run",
            file.to_str().unwrap(),
            "--out",
            killed.to_str().unwrap(),
            "-q",
            "--threads",
            "1",
        ],
        &killed,
        ",octomap,",
    );
    ok(run_into(&file, &killed, &[]));
    for name in [
        "runs.csv",
        "summary.csv",
        "paired.csv",
        "report.html",
        "map_octomap.bt",
    ] {
        assert_eq!(
            std::fs::read(whole.join(name)).unwrap(),
            std::fs::read(killed.join(name)).unwrap(),
            "{name} differs after the resume"
        );
    }
}

/// The example mapper in Python (mappers/ray_mapper.py) through the shipped
/// experiment that runs it: it reproduces OctoMap's update, so its rows
/// are the ray update's (scores within 1e-5: f64 against f32 sums).
#[test]
#[ignore = "needs python3; .ci/run runs it"]
fn the_python_example_mapper_runs_in_its_shipped_experiment() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    ok(run_into(
        &root().join("experiments/python_mapper.toml"),
        &out,
        &[],
    ));
    rows_match_the_ray_update(&out, "python_ray", 1e-5);
    has_paired(&out.join("paired.csv"), "python_ray", "ray_update", "f1");
}
