//! The warehouse hall (`experiments/hall.toml`, a workspace of 4.8e9 cells
//! at 1 cm), here at 5 cm to keep the test short: a run killed after its
//! first journaled seed and resumed, and shards of which one is killed and
//! resumed before the merge, write the files of an uninterrupted run byte
//! for byte.

mod common;

use common::{kill_once_journaled, ok, portable_experiment, run_args, run_into, sigmap_ok};
use std::path::{Path, PathBuf};

/// The hall experiment at 5 cm with three seeds, its paths absolute.
fn coarse_hall(dir: &Path) -> PathBuf {
    portable_experiment(
        "hall",
        dir,
        &[
            ("resolution = 0.01 ", "resolution = 0.05 "),
            ("seeds = [1, 2]", "seeds = [1, 2, 3]"),
        ],
    )
}

/// `sigmap run FILE --out OUT -q --threads 1 [extra]`, killed once a seed
/// is journaled.
fn kill_after_first_seed(file: &Path, out: &Path, extra: &[&str]) {
    let mut args = run_args(file, out, &["--threads", "1"]);
    args.extend_from_slice(extra);
    kill_once_journaled(&args, out, "#end ");
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
    let run = |out: &Path, extra: &[&str]| ok(run_into(&file, out, extra));
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
