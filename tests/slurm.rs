//! The quickstart on a real SLURM cluster: `sigmap submit` as a 4-task array
//! plus a dependent merge, checked byte for byte against a local run; then one
//! task cancelled, `sigmap status` reporting the hole and `--resume` filling it
//! with nothing lost or duplicated. `.ci/run` starts a single-node cluster
//! (`.ci/slurm.sh`); the test is `#[ignore]`d, and `.ci/run` runs it.

mod common;

use common::sigmap_ok;
use std::process::Command;
use std::time::{Duration, Instant};

fn require_slurm() {
    let present = Command::new("sbatch")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        present,
        "no `sbatch` on PATH; start a cluster with `bash .ci/slurm.sh start`"
    );
}

/// The job ids `sigmap submit` printed.
fn job_ids(stdout: &str) -> Vec<String> {
    stdout
        .lines()
        .filter_map(|l| {
            l.strip_prefix("submitted ")
                .and_then(|rest| rest.split_whitespace().last())
                .map(String::from)
        })
        .collect()
}

fn wait_for(ids: &[String]) {
    let start = Instant::now();
    loop {
        let out = Command::new("squeue")
            .args(["-h", "-j", &ids.join(",")])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        if text.trim().is_empty() {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "jobs still queued: {text}"
        );
        std::thread::sleep(Duration::from_millis(300));
    }
}

#[test]
#[ignore = "needs a SLURM controller (bash .ci/slurm.sh start); .ci/run runs it"]
fn quickstart_on_slurm_matches_a_local_run_and_resumes() {
    require_slurm();
    let dir = tempfile::tempdir().unwrap();
    let local = dir.path().join("local");
    sigmap_ok(&[
        "run",
        "experiments/quickstart.toml",
        "--out",
        local.to_str().unwrap(),
        "-q",
    ]);
    let read = |p: std::path::PathBuf| {
        std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    };

    // A whole sweep: 4 tasks and the merge.
    let cluster = dir.path().join("cluster");
    let stdout = sigmap_ok(&[
        "submit",
        "experiments/quickstart.toml",
        "--tasks",
        "4",
        "--out",
        cluster.to_str().unwrap(),
    ]);
    let ids = job_ids(&stdout);
    assert_eq!(ids.len(), 2, "{stdout}");
    wait_for(&ids);
    for file in ["runs.csv", "summary.csv"] {
        assert_eq!(read(cluster.join(file)), read(local.join(file)), "{file}");
    }
    assert!(cluster.join("sigmap_array.sbatch").exists() && cluster.join("coverage.svg").exists());
    let status = sigmap_ok(&["status", cluster.to_str().unwrap()]);
    assert!(status.contains("3 of 3 runs done; merged"), "{status}");

    // Task 2 cancelled before it runs: the merge never starts, status shows
    // the hole, --resume submits shard 2 only and the merge.
    let broken = dir.path().join("broken");
    let stdout = sigmap_ok(&[
        "submit",
        "experiments/quickstart.toml",
        "--tasks",
        "4",
        "--out",
        broken.to_str().unwrap(),
        "--sbatch-arg=--hold",
    ]);
    let ids = job_ids(&stdout);
    let (array, merge) = (&ids[0], &ids[1]);
    let cancel = Command::new("scancel")
        .arg(format!("{array}_2"))
        .status()
        .unwrap();
    assert!(cancel.success());
    for id in [array, merge] {
        assert!(Command::new("scontrol")
            .args(["release", id])
            .status()
            .unwrap()
            .success());
    }
    // The array finishes without task 2; the merge can never run: cancel it.
    let start = Instant::now();
    while !broken.join("shard_3").join("runs.csv").exists()
        || !broken.join("shard_1").join("runs.csv").exists()
    {
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "shards 1 and 3 did not finish"
        );
        std::thread::sleep(Duration::from_millis(300));
    }
    let _ = Command::new("scancel").arg(merge).status();
    wait_for(&ids);
    let status = sigmap_ok(&["status", broken.to_str().unwrap()]);
    assert!(
        status.contains("2 of 3 runs done") && status.contains("missing: seed 2"),
        "{status}"
    );
    assert!(!broken.join("summary.csv").exists());
    let stdout = sigmap_ok(&[
        "submit",
        "experiments/quickstart.toml",
        "--out",
        broken.to_str().unwrap(),
        "--resume",
    ]);
    assert!(stdout.contains("submitted shards 2 of 4"), "{stdout}");
    wait_for(&job_ids(&stdout));
    for file in ["runs.csv", "summary.csv"] {
        assert_eq!(
            read(broken.join(file)),
            read(local.join(file)),
            "{file} after --resume"
        );
    }
    // Nothing ran twice: every shard holds exactly its own runs.
    for shard in 1..=4 {
        let rows = std::fs::read_to_string(broken.join(format!("shard_{shard}")).join("runs.csv"))
            .unwrap();
        let expected = if shard == 4 { 0 } else { 3 };
        assert_eq!(rows.lines().skip(1).count(), expected, "shard {shard}");
    }
}

#[test]
fn submit_without_sbatch_says_so() {
    let out = Command::new(env!("CARGO_BIN_EXE_sigmap"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("PATH", "/nonexistent")
        .args(["submit", "experiments/quickstart.toml", "--tasks", "2"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no `sbatch` on PATH"));
}
