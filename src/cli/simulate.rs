//! `sigmap simulate`: the scans of one run, written to files.

use super::{progress_bar, with_threads, SimulateArgs};
use crate::error::Result;
use crate::experiment::{self, Experiment};
use std::time::Instant;

/// `sigmap simulate`.
pub(crate) fn run(args: SimulateArgs) -> Result<()> {
    let experiment = Experiment::load(&args.experiment)?;
    let seed = args.run.seed.unwrap_or(experiment.seed());
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| experiment::default_scan_dir(&experiment));
    super::print_notes(experiment.notes(), args.run.quiet);
    let bar = progress_bar(experiment.viewpoints().len(), "viewpoints", args.run.quiet);
    let start = Instant::now();
    let run = with_threads(args.run.threads, || {
        experiment::simulate(&experiment, seed, |done| bar.set_position(done as u64))
    })??;
    bar.finish_and_clear();
    let elapsed = start.elapsed().as_secs_f64();
    crate::files::write_folder(&out, |dir| experiment::write_scans(dir, &experiment, &run))?;
    let beams: usize = run.scans.iter().map(|s| s.measurements.len()).sum();
    let hits: usize = run
        .scans
        .iter()
        .map(|s| {
            s.measurements
                .iter()
                .filter(|m| m.status == crate::mapping::scan::BeamStatus::Hit)
                .count()
        })
        .sum();
    if !args.run.quiet {
        eprintln!(
            "simulated {} viewpoints, {beams} beams ({hits} hits) in {elapsed:.2} s ({:.2} M beams/s); wrote {}",
            run.scans.len(),
            beams as f64 / elapsed / 1e6,
            out.display()
        );
    }
    Ok(())
}
