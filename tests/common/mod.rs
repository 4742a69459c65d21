//! Helpers shared by the end-to-end tests.

use std::path::PathBuf;
use std::process::{Command, Output};

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The quickstart experiment's text with absolute paths, to edit and write
/// elsewhere.
#[allow(dead_code)] // not every test file edits experiments
pub fn portable_quickstart() -> String {
    let r = root().display().to_string();
    std::fs::read_to_string(root().join("experiments/quickstart.toml"))
        .unwrap()
        .replace("../", &format!("{r}/"))
        .replace(
            "profiles/collaborative.toml",
            &format!("{r}/experiments/profiles/collaborative.toml"),
        )
}

/// Runs the `sigmap` binary from the repository root.
pub fn sigmap(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sigmap"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("run sigmap")
}

/// Runs `sigmap`, checks it succeeded (showing its stderr if not), and
/// returns its stdout.
#[allow(dead_code)] // not every test file uses it
pub fn sigmap_ok(args: &[&str]) -> String {
    let out = sigmap(args);
    assert!(
        out.status.success(),
        "sigmap {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs an external tool to success (showing its stderr if not) and
/// returns its stdout.
#[allow(dead_code)] // not every test file runs a tool
pub fn tool_ok(command: &mut Command) -> String {
    let out = command.output().expect("run the tool");
    assert!(
        out.status.success(),
        "{command:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Fails, saying how to get it, unless python3 with `plyfile` runs (the
/// independent PLY reader of the ignored tests; `.ci/run` installs it).
#[allow(dead_code)] // not every test file reads a PLY
pub fn require_plyfile() {
    let probe = Command::new("python3")
        .args(["-c", "import plyfile"])
        .output();
    assert!(
        probe.is_ok_and(|o| o.status.success()),
        "python3 with plyfile not found (pip install plyfile; `bash .ci/run` does)"
    );
}

/// Simulates the quickstart into `dir` and checks it succeeded.
#[allow(dead_code)] // not every test file simulates
pub fn simulate_quickstart(dir: &std::path::Path, extra: &[&str]) {
    let mut args = vec![
        "simulate",
        "experiments/quickstart.toml",
        "--out",
        dir.to_str().unwrap(),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    let out = sigmap(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The shipped experiment `experiments/NAME.toml` with its paths absolute
/// and `edits` made (each must apply), written into `dir` as NAME.toml.
#[allow(dead_code)] // not every test file edits a shipped experiment
pub fn portable_experiment(name: &str, dir: &std::path::Path, edits: &[(&str, &str)]) -> PathBuf {
    let r = root().display().to_string();
    let mut text = std::fs::read_to_string(root().join(format!("experiments/{name}.toml")))
        .unwrap()
        .replace("\"../", &format!("\"{r}/"))
        .replace("\"profiles/", &format!("\"{r}/experiments/profiles/"));
    for (from, to) in edits {
        assert!(text.contains(from), "{name}.toml has no {from}");
        text = text.replace(from, to);
    }
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Starts `sigmap ARGS` (a `run` into `out`), kills it with SIGKILL once
/// `out`'s journal holds `needle`, and checks it had not finished.
#[allow(dead_code)] // not every test file kills a run
pub fn kill_once_journaled(args: &[&str], out: &std::path::Path, needle: &str) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_sigmap"))
        .args(args)
        .current_dir(root())
        .spawn()
        .expect("start sigmap");
    let journal = out.join("runs.journal.csv");
    // Polls a file another process writes; the guard only turns a run that
    // never journals into a failure instead of a hang.
    let start = std::time::Instant::now();
    while std::fs::read_to_string(&journal).map_or(true, |j| !j.contains(needle)) {
        assert!(start.elapsed().as_secs() < 600, "no run finished");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!out.join("summary.csv").exists(), "killed before the end");
}

/// The arguments `run FILE --out OUT -q EXTRA...`.
#[allow(dead_code)] // not every test file runs experiments
pub fn run_args<'a>(
    file: &'a std::path::Path,
    out: &'a std::path::Path,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec![
        "run",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
    ];
    args.extend_from_slice(extra);
    args
}

/// `sigmap run FILE --out OUT -q EXTRA...`.
#[allow(dead_code)] // not every test file runs experiments
pub fn run_into(
    file: &std::path::Path,
    out: &std::path::Path,
    extra: &[&str],
) -> std::process::Output {
    sigmap(&run_args(file, out, extra))
}

/// `sigmap run experiments/quickstart.toml --out OUT -q EXTRA...`, checked.
#[allow(dead_code)] // not every test file runs the quickstart
pub fn run_quickstart(out: &std::path::Path, extra: &[&str]) {
    ok(run_into(
        std::path::Path::new("experiments/quickstart.toml"),
        out,
        extra,
    ));
}

/// Asserts that `run` succeeded, showing its stderr if not.
#[allow(dead_code)] // not every test file runs experiments
pub fn ok(run: std::process::Output) {
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}

/// Runs sigmap and checks: exit 2, one line on stderr naming `names` and
/// saying `says`.
#[allow(dead_code)] // only the tests of bad input
pub fn refused(args: &[&str], names: &str, says: &str) {
    let out = sigmap(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    assert!(
        stderr.contains(names) && stderr.contains(says),
        "{args:?}: expected '{names}' and '{says}' in: {stderr}"
    );
}

/// `sigmap run` of the quickstart with `lines` added after its `seed = 1`
/// is refused (one line naming `names` and `says`, exit 2) and writes no
/// results folder.
#[allow(dead_code)] // only the tests of an experiment file's settings
pub fn quickstart_run_refused(lines: &str, names: &str, says: &str) {
    let dir = tempfile::tempdir().unwrap();
    let path = portable_experiment(
        "quickstart",
        dir.path(),
        &[("seed = 1", &format!("seed = 1\n{lines}"))],
    );
    let out = dir.path().join("out");
    let (path, out_arg) = (path.to_str().unwrap(), out.to_str().unwrap());
    refused(&["run", path, "--out", out_arg, "-q"], names, says);
    assert!(!out.exists());
}

/// Builds the C++ program `source` (a repository path) into `exe` with g++
/// against Debian's liboctomap-dev.
#[allow(dead_code)] // only the tests against liboctomap
pub fn build_against_liboctomap(source: &str, exe: &std::path::Path) {
    tool_ok(
        Command::new("g++")
            .args(["-O2", "-std=c++17"])
            .arg(root().join(source))
            .arg("-o")
            .arg(exe)
            .args(["-loctomap", "-loctomath"]),
    );
}

/// `sigmap map` of the quickstart's first run with the ray update, written
/// to `out` (`.ot` or `.bt`).
#[allow(dead_code)] // only the tests that score a map
pub fn quickstart_ray_update_map(out: &std::path::Path) {
    let out = out.to_str().unwrap();
    sigmap_ok(&[
        "map",
        "experiments/quickstart.toml",
        "--method",
        "ray_update",
        "-q",
        "--out",
        out,
    ]);
}
