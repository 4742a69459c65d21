//! The command line: argument parsing, progress, and exit codes
//! (0 ok, 1 a failed check, 2 bad input or usage).

use crate::error::{Error, Result};
use crate::experiment::{self, Experiment};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

/// Simulation-backed evaluation of uncertainty-aware occupancy maps.
#[derive(Parser, Debug)]
#[command(name = "sigmap", version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Simulate an experiment's scans: ray-cast every viewpoint from the true
    /// (error-drawn) sensor pose and write what the modeller receives (CSV, PLY,
    /// nominal chains with covariances) and, apart, the truth.
    Simulate(SimulateArgs),
}

#[derive(Args, Debug)]
struct SimulateArgs {
    /// The experiment file (TOML).
    experiment: PathBuf,
    /// Output folder [default: results/<experiment>/scans].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Seed of the run [default: the experiment's `seed`].
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (0: one per core). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

/// Runs `f` on a rayon pool of `threads` workers (0: one per core).
fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> Result<T> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::Usage(format!("cannot start {threads} threads: {e}")))?;
    Ok(pool.install(f))
}

fn progress_bar(len: usize, what: &str, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    if quiet || !std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    if let Ok(style) =
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} {elapsed} (eta {eta})")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_string());
    bar
}

fn simulate(args: SimulateArgs) -> Result<()> {
    let experiment = Experiment::load(&args.experiment)?;
    let seed = args.seed.unwrap_or(experiment.seed);
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| experiment::default_scan_dir(&experiment));
    let bar = progress_bar(experiment.viewpoints.len(), "viewpoints", args.quiet);
    let start = Instant::now();
    let run = with_threads(args.threads, || {
        experiment::simulate(&experiment, seed, |done| bar.set_position(done as u64))
    })??;
    bar.finish_and_clear();
    let elapsed = start.elapsed().as_secs_f64();
    experiment::write_atomically(&out, |dir| experiment::write_scans(dir, &experiment, &run))?;
    let beams: usize = run.scans.iter().map(|s| s.measurements.len()).sum();
    let hits: usize = run
        .scans
        .iter()
        .map(|s| {
            s.measurements
                .iter()
                .filter(|m| m.status == crate::sim::scan::BeamStatus::Hit)
                .count()
        })
        .sum();
    if !args.quiet {
        eprintln!(
            "simulated {} viewpoints, {beams} beams ({hits} hits) in {elapsed:.2} s ({:.2} M beams/s); wrote {}",
            run.scans.len(),
            beams as f64 / elapsed / 1e6,
            out.display()
        );
    }
    Ok(())
}

/// Parses the command line, runs the command, and returns the exit code.
pub fn main() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    let result = match cli.command {
        Command::Simulate(args) => simulate(args),
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}
