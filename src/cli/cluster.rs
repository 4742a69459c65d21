//! `sigmap submit` and `sigmap status`: the arguments and what is printed;
//! the SLURM logic is `experiment::study::cluster`.

use super::{StatusArgs, SubmitArgs};
use crate::error::{Error, Result};
use crate::experiment::study::cluster::{progress, read_submission, submit as submit_jobs};

/// `sigmap submit`.
pub(crate) fn submit(args: SubmitArgs) -> Result<()> {
    let done = submit_jobs(
        &args.experiment,
        args.tasks,
        args.out.as_deref(),
        &args.sbatch_arg,
        args.resume,
    )?;
    match &done.array_job {
        Some(id) => {
            let list: Vec<String> = done
                .shards
                .iter()
                .map(std::string::ToString::to_string)
                .collect();
            println!(
                "submitted shards {} of {} as job array {id}",
                list.join(","),
                done.tasks
            );
        }
        None => println!("every shard is complete; submitting the merge only"),
    }
    println!("submitted the merge as job {}", done.merge_job);
    println!(
        "watch: squeue -u $USER; sigmap status {}",
        done.out.display()
    );
    Ok(())
}

/// `sigmap status`.
pub(crate) fn status(args: StatusArgs) -> Result<()> {
    if !args.dir.join("submit.toml").is_file() {
        let what = if args.dir.join("run.toml").is_file() {
            "the results of `sigmap run` (no submit.toml): open its README.md or report.html"
        } else if args.dir.is_dir() {
            "not a submission of `sigmap submit` (no submit.toml)"
        } else {
            "not a folder"
        };
        return Err(Error::input(&args.dir, what));
    }
    let (submission, experiment) = read_submission(&args.dir)?;
    let states = progress(&experiment, &args.dir, submission.tasks)?;
    println!(
        "{:<7} {:>9} {:>6} {:>8}  state",
        "shard", "expected", "done", "missing"
    );
    let mut missing = 0;
    for s in &states {
        let state = match (&s.failed, s.missing.is_empty()) {
            (_, true) => "complete".to_string(),
            (Some(e), false) => format!("failed: {e}"),
            (None, false) => format!("missing: {}", s.missing.join(", ")),
        };
        println!(
            "{:<7} {:>9} {:>6} {:>8}  {state}",
            s.shard,
            s.expected,
            s.expected - s.missing.len(),
            s.missing.len()
        );
        missing += s.missing.len();
    }
    let merged = args.dir.join("summary.csv").exists() && missing == 0;
    println!(
        "{} of {} runs done{}",
        states
            .iter()
            .map(|s| s.expected - s.missing.len())
            .sum::<usize>(),
        states.iter().map(|s| s.expected).sum::<usize>(),
        if merged { "; merged" } else { "" }
    );
    if missing > 0 {
        println!(
            "resume with: sigmap submit {} --tasks {} --out {} --resume",
            submission.experiment.display(),
            submission.tasks,
            args.dir.display()
        );
    }
    Ok(())
}
