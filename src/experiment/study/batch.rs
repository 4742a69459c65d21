//! Batch runs of an experiment: every (sweep cell, seed) run, resumable from
//! a journal, sharded across machines and merged back. A results folder holds
//! `runs.csv`, `timings.csv`, `summary.csv`, the charts, the first run's maps
//! and `run.toml`, the manifest that ties it to its inputs (a resume or a
//! merge never reuses results of other inputs; docs/architecture.md).

use crate::error::{Error, Result};
use crate::eval::scores::wrong_cells;
use crate::experiment::output::folder_readme::write_folder_readme;
use crate::experiment::output::wrong_cells::{write_wrong_cells, ErrorsFormat};
use crate::experiment::run::runner::SeedOutcome;
use crate::experiment::run::runner::{read_rows, run_seed, write_rows, RunRow, TimingRow};
use crate::experiment::study::journal::{
    fingerprint, journal_record, read_journal, Inputs, Wanted, FINGERPRINT_SCHEME,
};
use crate::experiment::study::summary::{
    paired, paired_across_axes, summarise, PairedRow, SummaryRow,
};
use crate::experiment::Experiment;
use crate::experiment::RunMethod;
use crate::experiment::{
    charts::{results, slice},
    output::report,
};
use crate::mapping::octomap_io::write_octree;
use rayon::prelude::*;
use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// How `sigmap run` runs an experiment.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// The results folder (default: `results/<name>`).
    pub out: Option<PathBuf>,
    /// Redo every run, discarding the folder's earlier results.
    pub fresh: bool,
    /// Run only shard `i` of `n` (1-based); `None`: all runs.
    pub shard: Option<(usize, usize)>,
    /// Take over a lock another host holds (`--break-lock`).
    pub break_lock: bool,
}

/// What a finished batch run produced.
pub struct RunOutcome {
    /// The experiment (its base cell).
    pub experiment: Experiment,
    /// The results folder.
    pub out: PathBuf,
    /// The rows of `summary.csv`.
    pub summary: Vec<SummaryRow>,
    /// The rows of `paired.csv`.
    pub paired: Vec<PairedRow>,
    /// Runs (rows of `runs.csv`) in the folder.
    pub runs: usize,
}

/// The results folder of `experiment` unless one is given.
pub fn results_dir(experiment: &Experiment, out: Option<&Path>) -> PathBuf {
    out.map_or_else(
        || PathBuf::from("results").join(experiment.name()),
        Path::to_path_buf,
    )
}

/// Runs every (cell, seed) of the experiment file at `path` that the folder
/// does not hold yet (or every one of shard `i/n`), in parallel on the
/// current rayon pool, and writes the folder's files. A run is one method
/// on one seed's scans: `pending_runs(experiment, to_do, all)` is called
/// once, before the first run, with the runs to do and this shard's runs in
/// all, `finished(runs)` as each seed's runs are done.
pub fn run_experiment(
    path: &Path,
    options: &RunOptions,
    pending_runs: impl FnOnce(&Experiment, usize, usize),
    finished: impl Fn(usize) + Sync,
) -> Result<RunOutcome> {
    let (experiment, cells, labels) = load_cells(path)?;
    for cell in &cells {
        cell.check_truth_cost()?;
    }
    let out = results_dir(&experiment, options.out.as_deref());
    crate::files::claim_results_folder(&out)?;
    let _lock = crate::files::RunLock::acquire(&out, options.break_lock)?;
    let inputs = fingerprint(&cells)?;
    let (shard, shards) = options.shard.unwrap_or((1, 1));
    if options.fresh {
        discard_results(&out)?;
    } else {
        check_same_inputs(&out, &inputs, (shard, shards))?;
    }
    let wanted = Wanted {
        cells: &labels,
        seeds: experiment.seeds(),
        methods: experiment.methods(),
    };
    let Finished {
        mut rows,
        mut timings,
        done,
    } = finished_rows(&out, &wanted)?;
    let mine = shard_runs(cells.len(), experiment.seeds(), shard, shards);
    let all = mine.len();
    let pending: Vec<(usize, u64)> = mine
        .into_iter()
        .filter(|(c, s)| !done.contains(&(labels[*c].clone(), *s)))
        .collect();
    write_manifest(&out, &experiment, &inputs, shard, shards)?;
    let methods = experiment.methods().len();
    pending_runs(&experiment, pending.len() * methods, all * methods);
    let journal = Journal::open(&out.join(JOURNAL))?;
    let first = (0, experiment.seeds()[0]);
    let results: Vec<Result<(Vec<RunRow>, Vec<TimingRow>)>> = pending
        .par_iter()
        .map(|&(c, seed)| {
            let outcome = run_seed(&cells[c], seed)?;
            if (c, seed) == first {
                write_first_maps(&out, &cells[0], seed, &outcome)?;
            }
            journal.append(&outcome.rows, &outcome.timings)?;
            finished(outcome.rows.len());
            Ok((outcome.rows, outcome.timings))
        })
        .collect();
    for result in results {
        let (r, t) = result?;
        rows.extend(r);
        timings.extend(t);
    }
    let runs = rows.len();
    let (study, charts) = finalize(&out, &experiment, &labels, rows, timings)?;
    write_report_with_slice(&out, &experiment, &study, &inputs, charts)?;
    journal.remove()?;
    Ok(RunOutcome {
        experiment,
        out,
        summary: study.summary,
        paired: study.paired,
        runs,
    })
}

/// How a resume refused results of other inputs begins.
pub const OTHER_INPUTS: &str = "this folder holds results of other inputs";

/// The journal of finished runs, beside runs.csv while a run is under way.
const JOURNAL: &str = "runs.journal.csv";

/// The experiment at `path` (its base cell), every sweep cell loaded (and
/// so checked) before any run starts, and the cells' labels.
fn load_cells(path: &Path) -> Result<(Experiment, Vec<Experiment>, Vec<String>)> {
    let experiment = Experiment::load(path)?;
    let cells: Vec<Experiment> = experiment
        .cells()
        .iter()
        .map(|cell| Experiment::load_cell(path, cell))
        .collect::<Result<_>>()?;
    let labels = cells
        .iter()
        .map(|c| Experiment::cell_label(c.cell()))
        .collect();
    Ok((experiment, cells, labels))
}

/// `--fresh`: the folder's results of earlier runs, removed.
fn discard_results(out: &Path) -> Result<()> {
    for name in ["runs.csv", JOURNAL, "timings.csv"] {
        let path = out.join(name);
        if path.exists() {
            std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        }
    }
    Ok(())
}

/// Refuses to resume from results of other inputs: another version,
/// another shard, or files whose fingerprint changed (named).
fn check_same_inputs(out: &Path, inputs: &Inputs, (shard, shards): (usize, usize)) -> Result<()> {
    let manifest_path = out.join("run.toml");
    if !manifest_path.exists() {
        return Ok(());
    }
    let manifest: Manifest = crate::error::read_toml(&manifest_path)?;
    let version = env!("CARGO_PKG_VERSION");
    let what = if !manifest.fingerprint.starts_with(FINGERPRINT_SCHEME) {
        return Err(Error::input(
            &manifest_path,
            format!(
                "{OTHER_INPUTS}: their fingerprint '{}' is an older checksum that cannot \
                 vouch for their inputs (sigmap now fingerprints with SHA-256): rerun into \
                 another folder (--out) or remove this one",
                manifest.fingerprint
            ),
        ));
    } else if manifest.version != version {
        format!("sigmap {} wrote them, this is {version}", manifest.version)
    } else if manifest.shard != format!("{shard}/{shards}") {
        format!("they are shard {}, not {shard}/{shards}", manifest.shard)
    } else if manifest.fingerprint != inputs.fingerprint {
        let recorded: Vec<(String, String)> = manifest.inputs.into_iter().collect();
        let changed = inputs.changed_since(&recorded);
        if changed.is_empty() {
            "the sweep cells changed".to_string()
        } else {
            format!("changed since: {}", changed.join(", "))
        }
    } else {
        return Ok(());
    };
    Err(Error::input(
        &manifest_path,
        format!("{OTHER_INPUTS} ({what}): replace them, or write the results elsewhere"),
    ))
}

/// The finished runs of the folder: runs.csv and the journal of an
/// interrupted run. A run counts only with a row for every method; rows of
/// runs, methods or cells the experiment does not have are dropped, and so
/// are repeats.
fn finished_rows(out: &Path, wanted: &Wanted) -> Result<Finished> {
    let mut rows: Vec<RunRow> = read_rows(&out.join("runs.csv"))?;
    let (journal_rows, journal_timings) = read_journal(&out.join(JOURNAL))?;
    rows.extend(journal_rows);
    wanted.keep(&mut rows);
    let done = wanted.complete(&rows);
    rows.retain(|r| done.contains(&(r.cell.clone(), r.seed)));
    let mut timings: Vec<TimingRow> = read_rows(&out.join("timings.csv"))?;
    timings.extend(journal_timings);
    wanted.keep(&mut timings);
    timings.retain(|t| done.contains(&(t.cell.clone(), t.seed)));
    Ok(Finished {
        rows,
        timings,
        done,
    })
}

/// The finished runs of a results folder.
struct Finished {
    /// Their runs.csv rows.
    rows: Vec<RunRow>,
    /// Their timings.
    timings: Vec<TimingRow>,
    /// Which they are: (cell label, seed).
    done: BTreeSet<(String, u64)>,
}

/// The first run's maps (`map_<method>.bt`), the cells each calls wrongly
/// (`errors_<method>.ply`: the cells of its false-free and false-occupied
/// rates in runs.csv) and the slice through them and the truth
/// (`slice.svg`).
fn write_first_maps(out: &Path, cell: &Experiment, seed: u64, outcome: &SeedOutcome) -> Result<()> {
    let (truth, region, maps) = (&outcome.truth, &outcome.region, &outcome.maps);
    for (method, map) in cell.methods().iter().zip(maps) {
        write_octree(
            &out.join(format!("map_{method}.bt")),
            map,
            cell.map().clamp(),
        )?;
        write_wrong_cells(
            &out.join(format!("errors_{method}.ply")),
            ErrorsFormat::Ply,
            map,
            &wrong_cells(map, truth, &outcome.observable),
        )?;
    }
    let offset = cell.map_offset(seed);
    let workspace = &cell.scene().workspace;
    let mut workspace = crate::sim::scene::Bounds {
        min: workspace.min + offset,
        max: workspace.max + offset,
    };
    // The truth is known around the observed cells only: the slice spans
    // that part of the workspace.
    if let Some((min, max)) = region.corners(truth) {
        let known = crate::sim::scene::Bounds { min, max };
        if known.intersects(&workspace) {
            workspace.min = workspace.min.sup(&known.min);
            workspace.max = workspace.max.inf(&known.max);
        }
    }
    let pairs: Vec<_> = cell.methods().iter().cloned().zip(maps.iter()).collect();
    slice::plot_slice(
        &out.join("slice.svg"),
        truth,
        &pairs,
        &workspace,
        slice::slice_height(truth),
    )
}

/// The journal a run appends each finished (cell, seed) to, as one record,
/// so that an interruption loses only unfinished runs (a record cut short
/// is ignored when read).
struct Journal {
    path: PathBuf,
    file: Mutex<std::fs::File>,
}

impl Journal {
    fn open(path: &Path) -> Result<Self> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            file: Mutex::new(file),
        })
    }

    /// Appends one run's record and syncs it to disk.
    fn append(&self, rows: &[RunRow], timings: &[TimingRow]) -> Result<()> {
        let text = journal_record(rows, timings)?;
        let mut file = self
            .file
            .lock()
            .map_err(|_| Error::Internal("journal lock poisoned".into()))?;
        file.write_all(&text)
            .and_then(|()| file.sync_data())
            .map_err(|e| Error::io(&self.path, e))
    }

    /// Removes the journal once runs.csv holds every run.
    fn remove(self) -> Result<()> {
        std::fs::remove_file(&self.path).map_err(|e| Error::io(&self.path, e))
    }
}

/// The runs of shard `shard` of `shards` (1-based): every n-th (cell index,
/// seed) of the fixed list, cells outer. The same experiment always gives the
/// same shards.
pub fn shard_runs(cells: usize, seeds: &[u64], shard: usize, shards: usize) -> Vec<(usize, u64)> {
    (0..cells)
        .flat_map(|c| seeds.iter().map(move |&s| (c, s)))
        .enumerate()
        .filter(|(k, _)| k % shards == shard - 1)
        .map(|(_, run)| run)
        .collect()
}

/// The finished runs (cell label, seed) recorded in a run folder: its
/// runs.csv and the whole records of the journal of an interrupted run. A
/// run is finished when it has a row for every method it is `wanted` with.
pub fn finished_runs(dir: &Path, wanted: &Wanted) -> Result<BTreeSet<(String, u64)>> {
    let mut rows: Vec<RunRow> = read_rows(&dir.join("runs.csv"))?;
    rows.extend(read_journal(&dir.join("runs.journal.csv"))?.0);
    wanted.keep(&mut rows);
    Ok(wanted.complete(&rows))
}

/// What a finished study concludes: `summary.csv` and `paired.csv`.
pub struct Study {
    /// Each method's means over the seeds.
    pub summary: Vec<SummaryRow>,
    /// Each method against the reference, seed by seed.
    pub paired: Vec<PairedRow>,
}

/// Sorts the rows into the one order every machine agrees on (cell, seed,
/// method as the experiment lists them), writes runs.csv, timings.csv,
/// summary.csv, paired.csv and the summary's charts, and returns the study
/// and the charts written.
pub(super) fn finalize(
    out: &Path,
    experiment: &Experiment,
    labels: &[String],
    mut rows: Vec<RunRow>,
    mut timings: Vec<TimingRow>,
) -> Result<(Study, Vec<PathBuf>)> {
    let methods: &[RunMethod] = experiment.methods();
    let method_order = |m: &str| {
        methods
            .iter()
            .position(|x| x.as_str() == m)
            .unwrap_or(usize::MAX)
    };
    let cell_order = |c: &str| labels.iter().position(|x| x == c).unwrap_or(usize::MAX);
    rows.retain(|r| cell_order(&r.cell) != usize::MAX && method_order(&r.method) != usize::MAX);
    rows.sort_by_key(|r| (cell_order(&r.cell), r.seed, method_order(&r.method)));
    rows.dedup_by(|a, b| a.cell == b.cell && a.seed == b.seed && a.method == b.method);
    timings.sort_by_key(|r| (cell_order(&r.cell), r.seed, method_order(&r.method)));
    timings.dedup_by(|a, b| a.cell == b.cell && a.seed == b.seed && a.method == b.method);
    write_rows(&out.join("runs.csv"), &rows)?;
    write_rows(&out.join("timings.csv"), &timings)?;
    let summary = summarise(&rows, labels, methods);
    write_rows(&out.join("summary.csv"), &summary)?;
    let mut paired: Vec<PairedRow> = experiment
        .paired_references()
        .flat_map(|reference| paired(&rows, labels, methods, reference))
        .collect();
    paired.extend(paired_across_axes(
        &rows,
        experiment.sweep(),
        &experiment.cells(),
        methods,
    ));
    write_rows(&out.join("paired.csv"), &paired)?;
    let mut charts = results::plot_scores(
        &out.join("scores.svg"),
        &summary,
        &experiment.cells(),
        methods,
    )?;
    charts.extend(results::plot_safety(
        &out.join("safety.svg"),
        &summary,
        &experiment.cells(),
        methods,
    )?);
    let coverage = out.join("coverage.svg");
    results::plot_coverage(&coverage, &summary, &labels[0], methods)?;
    charts.push(coverage);
    write_folder_readme(out, experiment)?;
    Ok((Study { summary, paired }, charts))
}

/// Writes `report.html` from the folder's summary and `charts`, with the
/// first run's slice when the folder holds it.
pub(super) fn write_report_with_slice(
    out: &Path,
    experiment: &Experiment,
    study: &Study,
    inputs: &Inputs,
    mut charts: Vec<PathBuf>,
) -> Result<()> {
    let slice = out.join("slice.svg");
    if slice.is_file() {
        charts.push(slice);
    }
    report::write_report(out, experiment, study, inputs, &charts)
}

/// Writes `run.toml`: the experiment, the input fingerprint and each
/// input's hash, sigmap's version and the shard (serde, so any name is
/// valid TOML).
pub(super) fn write_manifest(
    out: &Path,
    experiment: &Experiment,
    inputs: &Inputs,
    shard: usize,
    shards: usize,
) -> Result<()> {
    let manifest = Manifest {
        experiment: experiment.name().to_string(),
        fingerprint: inputs.fingerprint.clone(),
        version: env!("CARGO_PKG_VERSION").into(),
        shard: format!("{shard}/{shards}"),
        inputs: inputs.files.iter().cloned().collect(),
        mappers: experiment
            .methods()
            .iter()
            .filter_map(|m| match m {
                RunMethod::External(mapper) => Some((mapper.name.clone(), mapper.command_line())),
                RunMethod::Own(_) => None,
            })
            .collect(),
    };
    let body = toml::to_string(&manifest).map_err(|e| Error::Internal(format!("run.toml: {e}")))?;
    let text = format!("# written by sigmap run; `sigmap run` and `sigmap merge` check it\n{body}");
    crate::files::write_file(&out.join("run.toml"), text.as_bytes())
}

/// `run.toml`: what a results folder was made from.
#[derive(serde::Deserialize, serde::Serialize)]
pub(super) struct Manifest {
    pub(super) experiment: String,
    pub(super) fingerprint: String,
    pub(super) version: String,
    pub(super) shard: String,
    #[serde(default)]
    pub(super) inputs: std::collections::BTreeMap<String, String>,
    /// Each external mapper's command, as it runs (placeholders unfilled).
    #[serde(default)]
    pub(super) mappers: std::collections::BTreeMap<String, String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_toml_stays_valid_whatever_the_names() {
        let dir = tempfile::tempdir().unwrap();
        let mut experiment = Experiment::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/experiments/quickstart.toml"
        )))
        .unwrap();
        *experiment.name_mut() = "a \"quoted\" name\nover two lines".into();
        let inputs = Inputs {
            fingerprint: "0123".into(),
            files: vec![("dir/with \"quote\".toml".into(), "beef".into())],
        };
        write_manifest(dir.path(), &experiment, &inputs, 2, 3).unwrap();
        let manifest: Manifest = crate::error::read_toml(&dir.path().join("run.toml")).unwrap();
        assert_eq!(manifest.experiment, experiment.name());
        assert_eq!(manifest.shard, "2/3");
        assert_eq!(manifest.inputs["dir/with \"quote\".toml"], "beef");
    }
}
