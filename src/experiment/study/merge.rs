//! `sigmap merge`: the folders of `sigmap run --shard i/n` joined into one
//! results folder, byte-identical to a one-machine run. Every shard must
//! have run the same inputs with this version, hold only the runs of its own
//! share (cell, seed, method as the experiment defines them), each once, and
//! together every run.

use crate::error::{Error, Result};
use crate::experiment::run::runner::{read_rows, RunRow, TimingRow};
use crate::experiment::study::batch::{
    finalize, results_dir, shard_runs, write_manifest, write_report_with_slice, Manifest,
};
use crate::experiment::study::journal::{fingerprint, read_journal, Inputs, Wanted};
use crate::experiment::Experiment;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Joins the folders of `sigmap run --shard i/n` of the experiment file at
/// `path` into `out` (default: `results/<name>`), checking that every shard
/// ran the same inputs with this version and that no run is missing; the
/// merged files are byte-identical to a one-machine run. Returns the folder.
pub fn merge_shards(path: &Path, shards: &[PathBuf], out: Option<&Path>) -> Result<PathBuf> {
    let experiment = Experiment::load(path)?;
    let labels: Vec<String> = experiment
        .cells()
        .iter()
        .map(|c| Experiment::cell_label(c))
        .collect();
    let cells: Vec<Experiment> = experiment
        .cells()
        .iter()
        .map(|cell| Experiment::load_cell(path, cell))
        .collect::<Result<_>>()?;
    let expected = fingerprint(&cells)?;
    let (mut rows, mut timings) = (Vec::new(), Vec::new());
    let mut seen_shards: Vec<(String, PathBuf)> = Vec::new();
    for dir in shards {
        let shard = Shard {
            dir,
            experiment: &experiment,
            path,
            labels: &labels,
        };
        let (shard_rows, shard_timings) = shard.read(&expected, &mut seen_shards)?;
        rows.extend(shard_rows);
        timings.extend(shard_timings);
    }
    // Each run once: a journal record of a run that runs.csv also holds
    // (a shard killed while it finalised) counts once.
    let wanted = Wanted {
        cells: &labels,
        seeds: experiment.seeds(),
        methods: experiment.methods(),
    };
    wanted.keep(&mut rows);
    wanted.keep(&mut timings);
    let missing = missing_runs(&experiment, &labels, &rows);
    if let Some(first) = missing.first() {
        return Err(Error::Usage(format!(
            "{} runs are missing from the shards (first: {first}); finish them with `sigmap run ... --shard i/n`",
            missing.len(),
        )));
    }
    let out = results_dir(&experiment, out);
    crate::files::claim_results_folder(&out)?;
    let _lock = crate::files::RunLock::acquire(&out, false)?;
    let (study, charts) = finalize(&out, &experiment, &labels, rows, timings)?;
    write_manifest(&out, &experiment, &expected, 1, 1)?;
    copy_first_run_files(shards, &out)?;
    write_report_with_slice(&out, &experiment, &study, &expected, charts)?;
    Ok(out)
}

/// One shard's folder of the experiment file at `path`.
struct Shard<'a> {
    dir: &'a Path,
    experiment: &'a Experiment,
    path: &'a Path,
    labels: &'a [String],
}

impl Shard<'_> {
    /// The shard's runs and timings (runs.csv and its journal), after
    /// checking that it ran the `expected` inputs with this version, that
    /// no shard of `seen` was the same share, and that it holds only runs
    /// of its share; its share is added to `seen`.
    fn read(
        &self,
        expected: &Inputs,
        seen: &mut Vec<(String, PathBuf)>,
    ) -> Result<(Vec<RunRow>, Vec<TimingRow>)> {
        let (dir, experiment) = (self.dir, self.experiment);
        let manifest_path = dir.join("run.toml");
        let manifest: Manifest = crate::error::read_toml(&manifest_path)?;
        if manifest.experiment != experiment.name() || manifest.fingerprint != expected.fingerprint
        {
            return Err(Error::input(
                &manifest_path,
                format!(
                    "this shard ran experiment '{}' with other inputs (fingerprint {} vs {}); merge only shards of {}",
                    manifest.experiment,
                    manifest.fingerprint,
                    expected.fingerprint,
                    self.path.display()
                ),
            ));
        }
        if manifest.version != env!("CARGO_PKG_VERSION") {
            return Err(Error::input(
                &manifest_path,
                format!(
                    "shard {} was written by sigmap {}, this is {}",
                    manifest.shard,
                    manifest.version,
                    env!("CARGO_PKG_VERSION")
                ),
            ));
        }
        let share = shard_share(&manifest, &manifest_path, experiment, self.labels)?;
        if let Some(other) = seen.iter().find(|(s, _)| *s == manifest.shard) {
            return Err(Error::input(
                &manifest_path,
                format!(
                    "shard {} is given twice (also {}); give each shard's folder once",
                    manifest.shard,
                    other.1.display()
                ),
            ));
        }
        seen.push((manifest.shard.clone(), dir.to_path_buf()));
        let mut rows: Vec<RunRow> = read_rows(&dir.join("runs.csv"))?;
        check_rows(&dir.join("runs.csv"), &rows, &share, experiment, 2)?;
        let (journal_rows, journal_timings) = read_journal(&dir.join("runs.journal.csv"))?;
        let journal = dir.join("runs.journal.csv");
        check_rows(&journal, &journal_rows, &share, experiment, 0)?;
        rows.extend(journal_rows);
        let mut timings = read_rows::<TimingRow>(&dir.join("timings.csv"))?;
        timings.extend(journal_timings);
        Ok((rows, timings))
    }
}

/// The runs (cell, seed, method) of `experiment` that `rows` lack, as
/// "cell 'c' seed s m", in the experiment's order.
fn missing_runs(experiment: &Experiment, labels: &[String], rows: &[RunRow]) -> Vec<String> {
    let have: BTreeSet<(&str, u64, &str)> = rows
        .iter()
        .map(|r| (r.cell.as_str(), r.seed, r.method.as_str()))
        .collect();
    let methods = experiment.methods();
    labels
        .iter()
        .flat_map(|c| {
            experiment
                .seeds()
                .iter()
                .flat_map(move |s| methods.iter().map(move |m| (c, *s, m)))
        })
        .filter(|(c, s, m)| !have.contains(&(c.as_str(), *s, m.as_str())))
        .map(|(c, s, m)| format!("cell '{c}' seed {s} {m}"))
        .collect()
}

/// The first run's maps, error clouds and slice, copied into `out` from
/// the shard that ran it.
fn copy_first_run_files(shards: &[PathBuf], out: &Path) -> Result<()> {
    for dir in shards {
        for entry in std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .flatten()
        {
            let name = entry.file_name().to_string_lossy().into_owned();
            let first_run = (name.starts_with("map_") && name.ends_with(".bt"))
                || (name.starts_with("errors_") && name.ends_with(".ply"));
            if name == "slice.svg" || first_run {
                std::fs::copy(entry.path(), out.join(&name))
                    .map_err(|e| Error::io(entry.path(), e))?;
            }
        }
    }
    Ok(())
}

/// The runs (cell label, seed) a shard's `run.toml` says it ran: its share
/// `i/n` of the experiment's runs.
fn shard_share(
    manifest: &Manifest,
    manifest_path: &Path,
    experiment: &Experiment,
    labels: &[String],
) -> Result<BTreeSet<(String, u64)>> {
    let parsed = manifest
        .shard
        .split_once('/')
        .and_then(|(i, n)| Some((i.parse::<usize>().ok()?, n.parse::<usize>().ok()?)))
        .filter(|&(i, n)| (1..=n).contains(&i));
    let Some((shard, shards)) = parsed else {
        return Err(Error::input(
            manifest_path,
            format!("shard = \"{}\" is not i/n with 1 <= i <= n", manifest.shard),
        ));
    };
    Ok(shard_runs(labels.len(), experiment.seeds(), shard, shards)
        .into_iter()
        .map(|(cell, seed)| (labels[cell].clone(), seed))
        .collect())
}

/// Refuses a row that is not a run of the shard's share and method of the
/// experiment, or that the file holds twice, naming the file and the row
/// (its line when `first_line` is the line of the first row, 0: its
/// position).
fn check_rows(
    path: &Path,
    rows: &[RunRow],
    share: &BTreeSet<(String, u64)>,
    experiment: &Experiment,
    first_line: usize,
) -> Result<()> {
    let mut seen = BTreeSet::new();
    for (index, row) in rows.iter().enumerate() {
        let at = if first_line > 0 {
            format!("line {}", first_line + index)
        } else {
            format!("row {}", index + 1)
        };
        let what = format!(
            "cell '{}' seed {} method {}",
            row.cell, row.seed, row.method
        );
        let problem = if !experiment
            .methods()
            .iter()
            .any(|m| m.as_str() == row.method)
        {
            Some("names a method the experiment does not have")
        } else if !share.contains(&(row.cell.clone(), row.seed)) {
            Some("is not a run of this shard (a cell or seed the experiment does not define, or another shard's run)")
        } else if !seen.insert((row.cell.as_str(), row.seed, row.method.as_str())) {
            Some("repeats a run and method the file already holds")
        } else {
            None
        };
        if let Some(problem) = problem {
            return Err(Error::input(
                path,
                format!(
                    "{at} ({what}) {problem}; merge only the folders `sigmap run --shard` wrote"
                ),
            ));
        }
    }
    Ok(())
}
