//! The `sigmap` command line: the arguments in `args.rs`, one clap adapter
//! per command, each in its own file (`run.rs` also holds `merge`,
//! `cluster.rs` `submit` and `status`).
//! An adapter parses arguments, calls the library (`experiment`, `mapping`,
//! `eval`, `uncertainty`), draws the progress bar and prints; it holds no
//! logic of its own. Exit codes: 0 ok, 1 a failed check, 2 bad input or
//! usage (`error`).

mod args;
mod cluster;
mod export;
mod ground_truth;
mod map;
mod opdf;
mod parse;
mod propagate;
mod regress;
mod run;
mod score;
mod simulate;

use crate::error::{Error, Result};
pub use args::Cli;
pub(crate) use args::*;
use clap::Parser;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
pub(crate) use parse::{resolution_arg, RiskArg};
use std::io::IsTerminal;

/// The line that says why the defaults' surface samples between beams are
/// off for `experiment`, if they are (docs/math.md §5.7).
pub(crate) fn samples_note(experiment: &crate::experiment::Experiment) -> Option<String> {
    experiment.samples_over_budget().map(|beams| {
        format!(
            "note: surface samples between beams are off: {beams} beams per viewpoint are more \
             than sigmap samples (set interpolate_beams = \"off\" to say so, or use larger \
             sensor steps to have them)"
        )
    })
}

/// Prints `notes` (the input files' `note: …` lines) on stderr unless
/// `quiet`.
pub(crate) fn print_notes(notes: &[String], quiet: bool) {
    if !quiet {
        for note in notes {
            eprintln!("{note}");
        }
    }
}

/// Runs `f` on a rayon pool of `threads` workers (0: one per core).
pub(crate) fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> Result<T> {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    if threads > 8 * cores.max(8) {
        return Err(Error::Usage(format!(
            "--threads {threads}: this machine has {cores} cores; use at most {} (0: one per core)",
            8 * cores.max(8)
        )));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::Usage(format!("cannot start {threads} threads: {e}")))?;
    Ok(pool.install(f))
}

/// An error of a sweep cell the experiment does not have names `--cell`.
pub(crate) fn cell_flag(e: Error) -> Error {
    if e.to_string().contains("sweep cells (0 to") {
        e.context("--cell: ")
    } else {
        e
    }
}

pub(crate) fn progress_bar(len: usize, what: &str, quiet: bool) -> ProgressBar {
    // Built, not set: nothing is drawn before the first length or step (a
    // bar of unknown length would flash full, "0/0").
    let mut bar = ProgressBar::new(len as u64).with_message(what.to_string());
    if quiet || !std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    if let Ok(style) =
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} {elapsed} (eta {eta})")
    {
        bar = bar.with_style(style.progress_chars("=> "));
    }
    bar
}

/// A spinner with the time elapsed, for a step whose length is not known
/// ahead (a truth over a whole workspace); hidden when `quiet` or when
/// stderr is not a terminal.
pub(crate) fn spinner(what: &str, quiet: bool) -> ProgressBar {
    let spinner = ProgressBar::new_spinner().with_message(what.to_string());
    if quiet || !std::io::stderr().is_terminal() {
        spinner.set_draw_target(ProgressDrawTarget::hidden());
        return spinner;
    }
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} {elapsed_precise}") {
        spinner.set_style(style);
    }
    spinner.enable_steady_tick(std::time::Duration::from_millis(250));
    spinner
}

/// Parses the command line, runs the command, and returns the exit code.
pub fn main() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            // A bad value or an unknown flag is one line naming the flag
            // and what is wrong (with the possible values); other usage
            // errors keep clap's usage lines.
            let one_line = [
                ErrorKind::ValueValidation,
                ErrorKind::InvalidValue,
                ErrorKind::UnknownArgument,
            ];
            if one_line.contains(&e.kind()) {
                let text = e.render().to_string();
                let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
                let first = lines.next().unwrap_or_default();
                let values = lines.find(|l| l.starts_with("[possible values"));
                match (e.kind(), values) {
                    (ErrorKind::UnknownArgument, _) => {
                        eprintln!("{first} (--help lists the flags)");
                    }
                    (_, Some(values)) => eprintln!("{first} {values}"),
                    _ => eprintln!("{first}"),
                }
            } else {
                let _ = e.print();
            }
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    exit_code_of(move || dispatch(cli.command))
}

/// Runs a command and gives the process's exit code: 0, or its error's
/// (printed as one line). A panic is a bug: its message (printed by the
/// hook) and the internal failure's code, never one that reads as bad input
/// or a failed check.
fn exit_code_of(command: impl FnOnce() -> Result<()> + std::panic::UnwindSafe) -> i32 {
    let Ok(result) = std::panic::catch_unwind(command) else {
        eprintln!(
            "error: internal error (a bug in sigmap; please report it with the command line)"
        );
        return crate::error::EXIT_INTERNAL;
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}

/// Runs one command.
fn dispatch(command: Command) -> Result<()> {
    match command {
        Command::Run(args) => run::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Export(args) => export::run(args),
        Command::Score(args) => score::run(args),
        Command::Propagate(args) => propagate::run(args),
        Command::Opdf(args) => opdf::run(args),
        Command::Map(args) => map::run(args),
        Command::GroundTruth(args) => ground_truth::run(args),
        Command::Regress(args) => regress::run(args),
        Command::Merge(args) => run::merge(args),
        Command::Submit(args) => cluster::submit(args),
        Command::Status(args) => cluster::status(args),
    }
}

#[cfg(test)]
mod exit_code_tests {
    use super::*;
    use crate::error::EXIT_INTERNAL;

    #[test]
    fn each_kind_of_failure_has_its_own_exit_code() {
        assert_eq!(exit_code_of(|| Ok(())), 0);
        assert_eq!(
            exit_code_of(|| Err(Error::CheckFailed("F1 fell".into()))),
            1
        );
        assert_eq!(exit_code_of(|| Err(Error::input("a.toml", "bad"))), 2);
        assert_eq!(exit_code_of(|| Err(Error::Usage("--x".into()))), 2);
        assert_eq!(exit_code_of(|| Err(Error::Internal("poisoned".into()))), 3);
        assert_eq!(exit_code_of(|| panic!("a bug")), EXIT_INTERNAL);
    }
}
