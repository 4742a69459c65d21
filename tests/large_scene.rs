//! The warehouse hall (`experiments/hall.toml`, a workspace of 4.8e9 cells
//! at 1 cm), here at 5 cm to keep the test short: a run killed after its
//! first journaled seed and resumed, and shards of which one is killed and
//! resumed before the merge, write the files of an uninterrupted run byte
//! for byte.

mod common;

use common::{root, sigmap_ok};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The hall experiment at 5 cm with three seeds, its paths absolute.
fn coarse_hall(dir: &Path) -> PathBuf {
    let r = root().display().to_string();
    let text = std::fs::read_to_string(root().join("experiments/hall.toml"))
        .unwrap()
        .replace("\"../", &format!("\"{r}/"))
        .replace("\"profiles/", &format!("\"{r}/experiments/profiles/"))
        .replace("resolution = 0.01 ", "resolution = 0.05 ")
        .replace("seeds = [1, 2]", "seeds = [1, 2, 3]");
    assert!(text.contains("resolution = 0.05") && text.contains("seeds = [1, 2, 3]"));
    let path = dir.join("hall.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Starts `sigmap run FILE --out OUT --threads 1 [extra]`, kills it with
/// SIGKILL once its journal holds a finished seed, and checks it had not
/// finished.
fn kill_after_first_seed(file: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec![
        "run",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
        "--threads",
        "1",
    ];
    args.extend_from_slice(extra);
    let mut child = Command::new(env!("CARGO_BIN_EXE_sigmap"))
        .args(&args)
        .spawn()
        .unwrap();
    let journal = out.join("runs.journal.csv");
    // Polls a file another process writes; the guard only turns a run that
    // never journals into a failure instead of a hang.
    let start = std::time::Instant::now();
    while std::fs::read_to_string(&journal).map_or(true, |j| !j.contains("#end ")) {
        assert!(start.elapsed().as_secs() < 600, "no seed finished");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!out.join("runs.csv").exists(), "killed before the end");
}

fn same_files(a: &Path, b: &Path, names: &[&str]) {
    for name in names {
        assert_eq!(
            std::fs::read(a.join(name)).unwrap(),
            std::fs::read(b.join(name)).unwrap(),
            "{name} differs"
        );
    }
}

#[test]
fn a_killed_run_and_a_killed_shard_of_the_hall_lose_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let file = coarse_hall(dir.path());
    let run = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "run",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "-q",
        ];
        args.extend_from_slice(extra);
        sigmap_ok(&args);
    };
    let whole = dir.path().join("whole");
    run(&whole, &[]);
    let files = ["runs.csv", "summary.csv", "paired.csv", "report.html"];
    // A run killed after its first seed, resumed.
    let killed = dir.path().join("killed");
    kill_after_first_seed(&file, &killed, &[]);
    run(&killed, &[]);
    same_files(&whole, &killed, &files);
    // Two shards, the first killed after its first seed and resumed, then
    // merged.
    let (first, second) = (dir.path().join("shard1"), dir.path().join("shard2"));
    kill_after_first_seed(&file, &first, &["--shard", "1/2"]);
    run(&first, &["--shard", "1/2"]);
    run(&second, &["--shard", "2/2"]);
    let merged = dir.path().join("merged");
    sigmap_ok(&[
        "merge",
        file.to_str().unwrap(),
        first.to_str().unwrap(),
        second.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    same_files(&whole, &merged, &files);
}
