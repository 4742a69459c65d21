//! `sigmap run` and `sigmap merge`: the arguments, the progress bar and the
//! headline; the batch logic is `experiment::study::batch`.

use super::{progress_bar, with_threads, MergeArgs, RunArgs};
use crate::error::Result;
use crate::experiment::output::report::HEADLINE;
use crate::experiment::study::batch::{run_experiment, RunOptions, OTHER_INPUTS};
use crate::experiment::study::merge::merge_shards;
use crate::experiment::study::summary::{PairedRow, SummaryRow};
use crate::experiment::Experiment;
use crate::uncertainty::consistency::Consistency;
use indicatif::ProgressBar;

/// `sigmap run`.
pub(crate) fn run(args: RunArgs) -> Result<()> {
    let options = RunOptions {
        out: args.out.clone(),
        fresh: args.fresh,
        shard: args.shard,
        break_lock: args.break_lock,
    };
    // A run is one method on one seed's scans: the bar counts them.
    let bar = progress_bar(0, "runs", args.run.quiet);
    let start = |experiment: &Experiment, pending: usize, all: usize| {
        if pending > 0 {
            bar.set_length(pending as u64);
        } else {
            // Nothing to count: no bar at all (it would show full, "0/0").
            bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
        }
        if pending > 0 && !args.run.quiet {
            announce_mappers(&bar, experiment);
            let notes = experiment.notes().iter().cloned();
            for note in notes.chain(super::samples_note(experiment)) {
                bar.suspend(|| eprintln!("{note}"));
            }
        }
        if pending < all && !args.run.quiet {
            bar.suspend(|| {
                eprintln!(
                    "resuming: {} of {all} runs already done, {pending} to do",
                    all - pending
                );
            });
        }
    };
    let finished = |runs: usize| bar.inc(runs as u64);
    let outcome = with_threads(args.run.threads, || {
        run_experiment(&args.experiment, &options, start, finished)
    })?
    .map_err(|e| {
        let stale = e.to_string().contains(OTHER_INPUTS)
            || e.to_string().contains("must be computed afresh");
        if stale {
            e.hint("rerun with --fresh to replace them, or choose another --out")
        } else {
            e
        }
    })?;
    ProgressBar::finish_and_clear(&bar);
    if !args.run.quiet {
        print_headline(&outcome.experiment, &outcome.summary, outcome.runs);
        print_consistency(&outcome.experiment, &outcome.summary);
        print_paired(&outcome.experiment, &outcome.paired);
        print_other_cells(&outcome.experiment);
        let methods = outcome.experiment.methods();
        let maps: Vec<String> = methods.iter().map(|m| format!("map_{m}.bt")).collect();
        let errors: Vec<String> = methods.iter().map(|m| format!("errors_{m}.ply")).collect();
        eprintln!(
            "wrote {}/runs.csv, summary.csv, paired.csv, timings.csv, {}, {}, report.html and \
             README.md (what each file holds)",
            outcome.out.display(),
            maps.join(", "),
            errors.join(", ")
        );
    }
    Ok(())
}

/// `sigmap merge`.
pub(crate) fn merge(args: MergeArgs) -> Result<()> {
    let out = merge_shards(&args.experiment, &args.shards, args.out.as_deref())?;
    eprintln!(
        "merged {} shards into {}/runs.csv, summary.csv, paired.csv, timings.csv and report.html",
        args.shards.len(),
        out.display()
    );
    Ok(())
}

fn print_headline(experiment: &Experiment, summary: &[SummaryRow], rows: usize) {
    // The headline is the first cell's (the whole sweep is in summary.csv).
    let first = summary.first().map(|s| s.cell.clone()).unwrap_or_default();
    let get = |method: &str, metric: &str| {
        summary
            .iter()
            .find(|s| s.cell == first && s.method == method && s.metric == metric)
            .map_or(f64::NAN, |s| s.mean)
    };
    use crate::experiment::output::count;
    println!(
        "{}: {} x {} ({}), {} m voxels; means over seeds{}",
        experiment.name(),
        count(experiment.seeds().len(), "seed"),
        count(experiment.methods().len(), "method"),
        count(rows, "run"),
        experiment.resolution(),
        if first.is_empty() {
            String::new()
        } else {
            format!(", cell {first}")
        }
    );
    let w = method_width(experiment);
    println!(
        "{:<w$} {:>7} {:>7} {:>7} {:>11} {:>9} {:>7} {:>8} {:>9}",
        "method", "prec", "recall", "F1", "false-free", "unknown", "Brier", "ROC AUC", "ANEES"
    );
    for method in experiment.methods() {
        let m = method.as_str();
        println!(
            "{:<w$} {:>7} {:>7} {:>7} {:>11} {:>9} {:>7} {:>8} {:>9}",
            m,
            number(get(m, "precision"), 3),
            number(get(m, "recall"), 3),
            number(get(m, "f1"), 3),
            number(get(m, "false_free_rate"), 4),
            number(get(m, "unknown_fraction"), 3),
            number(get(m, "brier"), 3),
            number(get(m, "roc_auc"), 3),
            number(get(m, "anees"), 2)
        );
    }
    println!(
        "(higher is better: prec, recall, F1, ROC AUC; lower: false-free = truly occupied cells \
         called free, unknown, Brier; ANEES: 3 = honest covariances, – = not propagated)"
    );
}

/// The first cell's per-point consistency check of each method that
/// propagates: the mean NEES of one point a run over the seeds against the
/// band honest covariances give it (report.html's table, every cell).
fn print_consistency(experiment: &Experiment, summary: &[SummaryRow]) {
    let first = summary.first().map(|s| s.cell.clone()).unwrap_or_default();
    let w = method_width(experiment);
    let mut header = false;
    for method in experiment.methods() {
        let Some(row) = summary.iter().find(|s| {
            s.cell == first
                && s.method == method.as_str()
                && s.metric == "nees_point"
                && s.n > 1
                && s.mean.is_finite()
        }) else {
            continue;
        };
        if !header {
            println!(
                "consistency (mean NEES of one point a run over the seeds; honest covariances \
                 put it in the 95% band 19 times in 20):"
            );
            header = true;
        }
        let (verdict, band) = Consistency::of_mean_nees(row.mean, row.n);
        println!(
            "{:<w$} {:>9.2}  band [{:.2}, {:.2}]  {}",
            method.as_str(),
            row.mean,
            band.0,
            band.1,
            verdict.as_str()
        );
    }
}

/// With a sweep, where the cells the terminal leaves out are.
fn print_other_cells(experiment: &Experiment) {
    let others = experiment.cells().len().saturating_sub(1);
    if others == 0 {
        return;
    }
    let across = if experiment
        .sweep()
        .iter()
        .any(|axis| axis.reference.is_some())
    {
        ", each cell against its axes' reference values"
    } else {
        ""
    };
    println!(
        "(the first of {} sweep cells; all of them{across}: summary.csv, paired.csv, report.html)",
        others + 1
    );
}

/// `v` with `digits` decimals, or `–` when there is no value.
fn number(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "–".into()
    }
}

/// Before the first run, the external programs the runs will start (also
/// recorded in run.toml).
fn announce_mappers(bar: &ProgressBar, experiment: &Experiment) {
    for method in experiment.methods() {
        if let crate::experiment::RunMethod::External(mapper) = method {
            bar.suspend(|| {
                eprintln!(
                    "mapper {} will run for each cell and seed: {}",
                    mapper.name,
                    mapper.command_line()
                );
            });
        }
    }
}

/// The method column as wide as the longest name (registered_truth, a
/// mapper's), at least 11.
fn method_width(experiment: &Experiment) -> usize {
    experiment
        .methods()
        .iter()
        .map(|m| m.as_str().len())
        .max()
        .unwrap_or(0)
        .max(11)
}

/// The first cell's paired comparisons: per method but the reference, each
/// metric's mean per-seed difference, its 95% interval and the verdict.
fn print_paired(experiment: &Experiment, paired: &[PairedRow]) {
    let first = paired.first().map(|p| p.cell.clone()).unwrap_or_default();
    if experiment.methods().len() < 2 || experiment.seeds().len() < 2 {
        return;
    }
    println!(
        "paired against {} (method - {}, per seed): mean [95% interval] verdict",
        experiment.reference(),
        experiment.reference()
    );
    let w = method_width(experiment);
    for method in experiment
        .methods()
        .iter()
        .filter(|&m| m != experiment.reference())
    {
        for (metric, title, digits) in HEADLINE {
            let Some(p) = paired.iter().find(|p| {
                p.is_between_methods()
                    && p.reference == experiment.reference().as_str()
                    && p.cell == first
                    && p.method == method.as_str()
                    && p.metric == metric
            }) else {
                continue;
            };
            println!(
                "{:<w$} {:<11} {:>+9.digits$} [{:>+9.digits$}, {:>+9.digits$}]  {}",
                if metric == HEADLINE[0].0 {
                    method.as_str()
                } else {
                    ""
                },
                title,
                p.mean,
                p.ci95_low,
                p.ci95_high,
                p.verdict.as_str()
            );
        }
    }
}
