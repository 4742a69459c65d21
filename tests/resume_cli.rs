//! End-to-end runs of `sigmap run` that stop and start: byte-identical
//! results whatever the thread count, resumption after an interruption, shards
//! merged into the one-machine result, and a resume that refuses the results
//! of other inputs.

mod common;

use common::{portable_quickstart, run_quickstart, sigmap};
use sigmap::experiment::run::runner::{RunRow, TimingRow};
use sigmap::experiment::study::journal::journal_record;

#[test]
fn results_do_not_depend_on_threads_and_survive_interruption() {
    let dir = tempfile::tempdir().unwrap();
    let (one, two) = (dir.path().join("one"), dir.path().join("two"));
    run_quickstart(&one, &["--threads", "1"]);
    run_quickstart(&two, &["--threads", "2"]);
    let read = |p: &std::path::Path| std::fs::read(p).unwrap();
    for file in ["runs.csv", "summary.csv", "paired.csv"] {
        assert_eq!(
            read(&one.join(file)),
            read(&two.join(file)),
            "{file} depends on the thread count"
        );
    }
    for method in ["blind", "unscented", "ray_update"] {
        assert!(one.join(format!("map_{method}.bt")).exists());
    }
    for chart in ["coverage.svg", "slice.svg"] {
        let svg = std::fs::read_to_string(one.join(chart)).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.contains("unscented"),
            "{chart}"
        );
    }
    assert!(std::fs::read_to_string(one.join("slice.svg"))
        .unwrap()
        .contains("false-free"));
    // An interrupted run: the first seed's record reached the journal whole
    // (with a marked F1, to see that it is reused, not recomputed), the
    // second seed's was cut mid-record. The re-run keeps the first and
    // recomputes the second and third.
    let runs = String::from_utf8(read(&one.join("runs.csv"))).unwrap();
    let lines: Vec<&str> = runs.lines().collect();
    let rows = |from: usize| -> Vec<RunRow> {
        csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(lines[from..from + 3].join("\n").as_bytes())
            .deserialize()
            .map(|r| r.unwrap())
            .collect()
    };
    let mut first = rows(1);
    first[0].set("f1", 0.123456);
    let timings: Vec<TimingRow> = csv::Reader::from_path(one.join("timings.csv"))
        .unwrap()
        .deserialize()
        .map(|r| r.unwrap())
        .collect();
    let second = journal_record(&rows(4), &timings[3..6]).unwrap();
    let mut journal = journal_record(&first, &timings[..3]).unwrap();
    journal.extend_from_slice(&second[..second.len() - 5]);
    let resumed = dir.path().join("resumed");
    std::fs::create_dir_all(&resumed).unwrap();
    std::fs::write(resumed.join("runs.journal.csv"), journal).unwrap();
    run_quickstart(&resumed, &[]);
    let got = String::from_utf8(read(&resumed.join("runs.csv"))).unwrap();
    assert!(got.contains("0.123456"), "the whole record is reused");
    assert_eq!(got.lines().count(), lines.len());
    assert_eq!(got.lines().skip(2).collect::<Vec<_>>(), lines[2..].to_vec());
    // The reused run keeps its timings (from the journal record).
    let resumed_timings = std::fs::read_to_string(resumed.join("timings.csv")).unwrap();
    assert_eq!(resumed_timings.lines().count(), timings.len() + 1);
    assert!(resumed_timings.contains(&format!("{}", timings[0].model_s)));
    // With --fresh everything is recomputed.
    run_quickstart(&resumed, &["--fresh"]);
    assert_eq!(read(&resumed.join("runs.csv")), read(&one.join("runs.csv")));
    assert!(!resumed.join("runs.journal.csv").exists());
    // A re-run with everything done changes nothing.
    run_quickstart(&resumed, &[]);
    assert_eq!(read(&resumed.join("runs.csv")), read(&one.join("runs.csv")));
}

#[test]
fn shards_merge_into_the_one_machine_result() {
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole");
    run_quickstart(&whole, &[]);
    let shard = |i: &str| {
        let out = dir.path().join(format!("shard{}", &i[..1]));
        run_quickstart(&out, &["--shard", i]);
        out
    };
    let (a, b) = (shard("1/2"), shard("2/2"));
    let read = |p: &std::path::Path| std::fs::read(p).unwrap();
    assert_ne!(
        read(&a.join("runs.csv")),
        read(&whole.join("runs.csv")),
        "a shard holds part of the runs"
    );
    // `sigmap merge` of the quickstart's shard folders into `into`.
    let merge_into = |shards: &[&std::path::Path], into: &std::path::Path| {
        let mut args = vec!["merge", "experiments/quickstart.toml"];
        args.extend(shards.iter().map(|d| d.to_str().unwrap()));
        args.extend(["--out", into.to_str().unwrap()]);
        sigmap(&args)
    };
    let merged = dir.path().join("merged");
    let out = merge_into(&[&a, &b], &merged);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The report too: the same summary, charts, slice and fingerprint; and
    // the first run's map and error cloud, from the shard that ran it.
    let first_run = ["map_unscented.bt", "errors_unscented.ply"];
    for file in ["runs.csv", "summary.csv", "paired.csv", "report.html"]
        .into_iter()
        .chain(first_run)
    {
        assert_eq!(read(&merged.join(file)), read(&whole.join(file)), "{file}");
    }
    // A missing shard, an out-of-range shard, and a shard of another experiment are refused.
    let out = merge_into(&[&a], &dir.path().join("m2"));
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing"));
    let out = sigmap(&["run", "experiments/quickstart.toml", "--shard", "3/2"]);
    assert_eq!(out.status.code(), Some(2));
    // A shard's runs.csv with a row the experiment does not define (seed
    // 9), a row twice, or the same shard given twice: refused, naming the
    // file and the row, and nothing merged.
    let merge = |dirs: &[&std::path::Path], says: &[&str]| {
        let into = dir.path().join("refused");
        let out = merge_into(dirs, &into);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        for s in says {
            assert!(stderr.contains(s), "{s} in {stderr}");
        }
        assert!(!into.join("runs.csv").exists());
    };
    let runs = a.join("runs.csv");
    let original = std::fs::read_to_string(&runs).unwrap();
    let last = original.lines().last().unwrap();
    let mut fields: Vec<&str> = last.split(',').collect();
    fields[1] = "9";
    std::fs::write(&runs, format!("{original}{}\n", fields.join(","))).unwrap();
    let line = original.lines().count() + 1;
    merge(
        &[&a, &b],
        &[
            "shard1/runs.csv",
            &format!("line {line}"),
            "seed 9",
            "not a run",
        ],
    );
    std::fs::write(&runs, format!("{original}{last}\n")).unwrap();
    merge(&[&a, &b], &["shard1/runs.csv", "repeats a run"]);
    std::fs::write(&runs, &original).unwrap();
    merge(&[&a, &b, &a], &["shard 1/2 is given twice"]);
    // A folder of the user's own files takes neither a merge nor a run:
    // its runs.csv stays theirs.
    let mine = dir.path().join("mine");
    std::fs::create_dir_all(&mine).unwrap();
    std::fs::write(mine.join("runs.csv"), "my own table\n").unwrap();
    for out in [
        merge_into(&[&a, &b], &mine),
        sigmap(&[
            "run",
            "experiments/quickstart.toml",
            "--out",
            mine.to_str().unwrap(),
        ]),
    ] {
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(
            stderr.contains("holds files sigmap did not write"),
            "{stderr}"
        );
    }
    assert_eq!(
        std::fs::read_to_string(mine.join("runs.csv")).unwrap(),
        "my own table\n"
    );
    assert_eq!(std::fs::read_dir(&mine).unwrap().count(), 1);
    // Nor does a folder a live sigmap is writing into (its lock held by
    // this test's own process).
    let busy = dir.path().join("busy");
    std::fs::create_dir_all(&busy).unwrap();
    std::fs::write(
        busy.join(".sigmap-run.lock"),
        std::process::id().to_string(),
    )
    .unwrap();
    let out = merge_into(&[&a, &b], &busy);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("is writing into this folder"), "{stderr}");
    assert!(!busy.join("runs.csv").exists());
    let manifest = std::fs::read_to_string(b.join("run.toml"))
        .unwrap()
        .replace("quickstart", "paper");
    std::fs::write(b.join("run.toml"), manifest).unwrap();
    let out = merge_into(&[&a, &b], &dir.path().join("m3"));
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("run.toml"));
}

/// Results of other inputs are never reused: editing the profile, a mesh of
/// the scene, or the experiment and re-running into the same folder is
/// refused (exit 2) until `--fresh`.
#[test]
fn a_resume_refuses_results_of_other_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let root = env!("CARGO_MANIFEST_DIR");
    let profile = dir.path().join("profile.toml");
    let mesh = dir.path().join("bunny.obj");
    let scene = dir.path().join("scene.toml");
    std::fs::copy(
        format!("{root}/experiments/profiles/collaborative.toml"),
        &profile,
    )
    .unwrap();
    std::fs::copy(format!("{root}/scenes/meshes/bunny.obj"), &mesh).unwrap();
    std::fs::write(
        &scene,
        std::fs::read_to_string(format!("{root}/scenes/tabletop.toml"))
            .unwrap()
            .replace("meshes/bunny.obj", mesh.to_str().unwrap()),
    )
    .unwrap();
    let experiment = dir.path().join("e.toml");
    let text = portable_quickstart()
        .replace(
            &format!("{root}/scenes/tabletop.toml"),
            scene.to_str().unwrap(),
        )
        .replace(
            &format!("{root}/experiments/profiles/collaborative.toml"),
            profile.to_str().unwrap(),
        )
        .replace("seeds = [1, 2, 3]", "seeds = [1]")
        .replace(
            r#"methods = ["blind", "unscented", "ray_update"]"#,
            r#"methods = ["ray_update"]"#,
        );
    std::fs::write(&experiment, &text).unwrap();
    let out = dir.path().join("out");
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "run".to_string(),
            experiment.to_str().unwrap().to_string(),
            "--out".into(),
            out.to_str().unwrap().into(),
            "-q".into(),
        ];
        a.extend(extra.iter().map(std::string::ToString::to_string));
        a
    };
    let call = |extra: &[&'static str]| {
        let a = args(extra);
        sigmap(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    assert!(call(&[]).status.success());
    assert!(call(&[]).status.success(), "the same inputs resume");
    let edits: [(&std::path::Path, &str); 3] = [
        (&profile, "\n# an edit\n"),
        (&mesh, "\n# an edit\n"),
        (&experiment, "\n# an edit\n"),
    ];
    for (file, edit) in edits {
        let mut text = std::fs::read_to_string(file).unwrap();
        text.push_str(edit);
        std::fs::write(file, &text).unwrap();
        let refused = call(&[]);
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert_eq!(
            refused.status.code(),
            Some(2),
            "{}: {stderr}",
            file.display()
        );
        assert!(
            stderr.contains("other inputs") && stderr.contains("--fresh"),
            "{stderr}"
        );
        assert!(call(&["--fresh"]).status.success());
    }
    // A folder fingerprinted with the old 64-bit checksum, however well its
    // inputs match, is not resumed from.
    let manifest = out.join("run.toml");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("fingerprint = "))
        .unwrap();
    std::fs::write(
        &manifest,
        text.replace(line, "fingerprint = \"4f1c0a9be2d37a65\""),
    )
    .unwrap();
    let refused = call(&[]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("4f1c0a9be2d37a65") && stderr.contains("SHA-256"),
        "{stderr}"
    );
    assert!(call(&["--fresh"]).status.success());
    let text = std::fs::read_to_string(&manifest).unwrap();
    assert!(text.contains("fingerprint = \"sha256:"), "{text}");
}
