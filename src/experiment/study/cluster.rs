//! SLURM: an experiment as a job array of shards (`sigmap run --shard k/N`)
//! plus a dependent merge, on the batch system the cluster already has
//! (docs/slurm.md). The submission is recorded in `submit.toml`, so that
//! its progress can be read back and the missing shards resubmitted.

use crate::error::{Error, Result};
use crate::experiment::study::batch::{finished_runs, shard_runs};
use crate::experiment::study::journal::Wanted;
use crate::experiment::Experiment;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::process::Command;

/// `submit.toml`: what was submitted, so that `status` and `--resume` know
/// the experiment and the number of shards.
#[derive(Serialize, Deserialize)]
pub struct Submission {
    /// The experiment file (absolute).
    pub experiment: PathBuf,
    /// Array tasks (shards).
    pub tasks: usize,
    /// The sigmap binary the tasks run.
    pub sigmap: PathBuf,
}

/// Progress of one shard.
pub struct ShardState {
    /// Its number (1-based).
    pub shard: usize,
    /// Runs it has to do.
    pub expected: usize,
    /// Its runs not finished yet, as `cell seed s`.
    pub missing: Vec<String>,
    /// The error its log ended with, if it failed.
    pub failed: Option<String>,
}

/// What [`submit`] queued.
pub struct Submitted {
    /// The shards submitted (all, or with `resume` those missing runs).
    pub shards: Vec<usize>,
    /// Array tasks of the submission.
    pub tasks: usize,
    /// The job id of the array (none when every shard was complete).
    pub array_job: Option<String>,
    /// The job id of the merge.
    pub merge_job: String,
    /// The results folder (absolute).
    pub out: PathBuf,
}

fn absolute(path: &Path) -> Result<PathBuf> {
    std::fs::canonicalize(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::input(path, "file not found"),
        _ => Error::io(path, e),
    })
}

fn shard_dir(out: &Path, shard: usize) -> PathBuf {
    out.join(format!("shard_{shard}"))
}

/// The progress of each shard of a submission in `out`.
pub fn progress(experiment: &Experiment, out: &Path, tasks: usize) -> Result<Vec<ShardState>> {
    let labels: Vec<String> = experiment
        .cells()
        .iter()
        .map(|c| Experiment::cell_label(c))
        .collect();
    (1..=tasks)
        .map(|shard| {
            let dir = shard_dir(out, shard);
            let wanted = Wanted {
                cells: &labels,
                seeds: experiment.seeds(),
                methods: experiment.methods(),
            };
            let done = finished_runs(&dir, &wanted)?;
            let expected = shard_runs(labels.len(), experiment.seeds(), shard, tasks);
            let missing = expected
                .iter()
                .filter(|(c, s)| !done.contains(&(labels[*c].clone(), *s)))
                .map(|(c, s)| {
                    if labels[*c].is_empty() {
                        format!("seed {s}")
                    } else {
                        format!("{} seed {s}", labels[*c])
                    }
                })
                .collect();
            // A task that ended in an error leaves it as the last line of its log.
            let log = out.join("logs").join(format!("shard_{shard}.log"));
            let failed = std::fs::read_to_string(&log).ok().and_then(|t| {
                t.lines()
                    .rev()
                    .find(|l| l.starts_with("error:") || l.contains("CANCELLED"))
                    .map(String::from)
            });
            Ok(ShardState {
                shard,
                expected: expected.len(),
                missing,
                failed,
            })
        })
        .collect()
}

fn sbatch(args: &[String], script: &Path) -> Result<String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .arg(script)
        .output()
        .map_err(|e| Error::Usage(format!("cannot run sbatch: {e}")))?;
    if !out.status.success() {
        return Err(Error::Usage(format!(
            "sbatch refused {}: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    let text = String::from_utf8_lossy(&out.stdout);
    Ok(text
        .trim()
        .split(';')
        .next()
        .unwrap_or_default()
        .to_string())
}

fn quote(path: &Path) -> String {
    format!("'{}'", path.display().to_string().replace('\'', "'\\''"))
}

/// Most array tasks (shards) of one submission.
pub const MAX_TASKS: usize = 10_000;

/// Submits the experiment file at `path` as `tasks` shards and a merge,
/// into `out` (default: `results/<name>`); with `resume`, only the shards
/// of the earlier submission in `out` that miss runs. `sbatch_args` go to
/// every sbatch call.
pub fn submit(
    path: &Path,
    tasks: usize,
    out: Option<&Path>,
    sbatch_args: &[String],
    resume: bool,
) -> Result<Submitted> {
    if !(1..=MAX_TASKS).contains(&tasks) {
        return Err(Error::Usage(format!(
            "{tasks} tasks: a submission has between 1 and {MAX_TASKS} tasks"
        )));
    }
    if Command::new("sbatch").arg("--version").output().is_err() {
        return Err(Error::Usage(
            "no `sbatch` on PATH: `sigmap submit` needs SLURM's client tools (run the shards by hand with \
             `sigmap run --shard i/n` and join them with `sigmap merge`)"
                .into(),
        ));
    }
    let experiment_path = absolute(path)?;
    let experiment = Experiment::load(&experiment_path)?;
    // Every cell is checked here, before anything is queued.
    for cell in experiment.cells() {
        Experiment::load_cell(&experiment_path, &cell)?;
    }
    let out = crate::experiment::study::batch::results_dir(&experiment, out);
    crate::files::claim_results_folder(&out)?;
    std::fs::create_dir_all(out.join("logs")).map_err(|e| Error::io(&out, e))?;
    let out = absolute(&out)?;
    let sigmap = std::env::current_exe()
        .map_err(|e| Error::Usage(format!("cannot find the sigmap binary: {e}")))?;
    let tasks = if resume {
        previous_tasks(&out, &experiment_path)?
    } else {
        tasks
    };
    let submission = Submission {
        experiment: experiment_path,
        tasks,
        sigmap,
    };
    let manifest = toml::to_string(&submission).map_err(|e| Error::Usage(e.to_string()))?;
    std::fs::write(out.join("submit.toml"), manifest)
        .map_err(|e| Error::io(out.join("submit.toml"), e))?;
    let scripts = write_scripts(&out, experiment.name(), &submission)?;
    let todo: Vec<usize> = if resume {
        progress(&experiment, &out, tasks)?
            .into_iter()
            .filter(|s| !s.missing.is_empty())
            .map(|s| s.shard)
            .collect()
    } else {
        (1..=tasks).collect()
    };
    let (array_job, merge_job) = queue(&scripts, &todo, sbatch_args)?;
    Ok(Submitted {
        shards: todo,
        tasks,
        array_job,
        merge_job,
        out,
    })
}

/// The tasks of the earlier submission in `out`, which must be of the
/// same experiment.
fn previous_tasks(out: &Path, experiment_path: &Path) -> Result<usize> {
    let manifest = out.join("submit.toml");
    let previous: Submission = crate::error::read_toml(&manifest)?;
    if previous.experiment != experiment_path {
        return Err(Error::input(
            &manifest,
            format!(
                "this folder holds a submission of {}, not of {}",
                previous.experiment.display(),
                experiment_path.display()
            ),
        ));
    }
    if !(1..=MAX_TASKS).contains(&previous.tasks) {
        return Err(Error::input(
            &manifest,
            format!(
                "tasks = {} must be between 1 and {MAX_TASKS}",
                previous.tasks
            ),
        ));
    }
    Ok(previous.tasks)
}

/// The two batch scripts of a submission.
struct Scripts {
    /// The job array: task k runs shard k.
    array: PathBuf,
    /// The merge of the shards.
    merge: PathBuf,
}

/// Writes the job array's and the merge's scripts into `out`.
fn write_scripts(out: &Path, name: &str, submission: &Submission) -> Result<Scripts> {
    let tasks = submission.tasks;
    let (sigmap, experiment) = (quote(&submission.sigmap), quote(&submission.experiment));
    let logs = out.join("logs");
    let array = out.join("sigmap_array.sbatch");
    let script = format!(
        "#!/bin/bash\n\
         # One shard of {name}: task k runs every {tasks}-th run of the experiment.\n\
         # Written by `sigmap submit`; adapt freely (partition, time, memory: add #SBATCH lines).\n\
         #SBATCH --job-name=sigmap-{name}\n\
         #SBATCH --output={logs}/shard_%a.log\n\
         set -euo pipefail\n\
         exec {sigmap} run {experiment} --shard \"$SLURM_ARRAY_TASK_ID/{tasks}\" \\\n    \
         --out {out}/shard_\"$SLURM_ARRAY_TASK_ID\" --threads \"${{SLURM_CPUS_PER_TASK:-1}}\" --quiet\n",
        logs = logs.display(),
        out = quote(out),
    );
    std::fs::write(&array, script).map_err(|e| Error::io(&array, e))?;
    let shards: Vec<String> = (1..=tasks).map(|k| quote(&shard_dir(out, k))).collect();
    let merge = out.join("sigmap_merge.sbatch");
    let script = format!(
        "#!/bin/bash\n\
         # Joins the shards of {name} into runs.csv, summary.csv and the charts. Written by `sigmap submit`.\n\
         #SBATCH --job-name=sigmap-{name}-merge\n\
         #SBATCH --output={logs}/merge.log\n\
         set -euo pipefail\n\
         exec {sigmap} merge {experiment} {shards} --out {out}\n",
        logs = logs.display(),
        shards = shards.join(" "),
        out = quote(out),
    );
    std::fs::write(&merge, script).map_err(|e| Error::io(&merge, e))?;
    Ok(Scripts { array, merge })
}

/// Queues the array of the shards `todo` (none: no array) and the merge
/// after it; returns their job ids.
fn queue(
    scripts: &Scripts,
    todo: &[usize],
    sbatch_args: &[String],
) -> Result<(Option<String>, String)> {
    let mut dependency = Vec::new();
    let mut array_job = None;
    if !todo.is_empty() {
        let list: Vec<String> = todo.iter().map(ToString::to_string).collect();
        let mut array_args = vec![format!("--array={}", list.join(","))];
        array_args.extend(sbatch_args.iter().cloned());
        let id = sbatch(&array_args, &scripts.array)?;
        dependency.push(format!("--dependency=afterok:{id}"));
        array_job = Some(id);
    }
    dependency.extend(sbatch_args.iter().cloned());
    let merge_job = sbatch(&dependency, &scripts.merge).map_err(|e| match &array_job {
        Some(id) => Error::Usage(format!(
            "{e} (the shards went in as job array {id}; queue the merge with \
             `sbatch --dependency=afterok:{id} {}`)",
            scripts.merge.display()
        )),
        None => e,
    })?;
    Ok((array_job, merge_job))
}

/// Reads the submission recorded in `dir` and its experiment.
pub fn read_submission(dir: &Path) -> Result<(Submission, Experiment)> {
    let manifest = dir.join("submit.toml");
    let submission: Submission = crate::error::read_toml(&manifest)?;
    if !(1..=MAX_TASKS).contains(&submission.tasks) {
        return Err(Error::input(
            &manifest,
            format!(
                "tasks = {} must be between 1 and {MAX_TASKS}",
                submission.tasks
            ),
        ));
    }
    let experiment = Experiment::load(&submission.experiment)?;
    Ok((submission, experiment))
}
