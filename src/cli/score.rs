//! `sigmap score`: any OctoMap file scored as `sigmap run` scores its maps
//! (`experiment::runner::score_external`).

use super::{with_threads, ScoreArgs};
use crate::error::Result;
use crate::experiment::metrics::{Kind, METRICS};
use crate::experiment::runner::{append_row, score_external};
use crate::experiment::Experiment;
use crate::mapping::octomap_io::read_octree;

/// `sigmap score`.
pub(crate) fn run(args: ScoreArgs) -> Result<()> {
    let experiment = Experiment::load_cell_index(&args.experiment, args.cell)?;
    let seed = args.run.seed.unwrap_or(experiment.seed);
    let map = read_octree(&args.map, experiment.map.clamp())?;
    let name = crate::sim::scene::stem(&args.map);
    let row = with_threads(args.run.threads, || {
        score_external(&experiment, seed, &map, &name)
    })??;
    if let Some(path) = &args.csv {
        append_row(path, &row)?;
    }
    if !args.run.quiet {
        println!(
            "{} against experiment '{}', seed {seed}{}:",
            args.map.display(),
            experiment.name,
            match Experiment::cell_label(&experiment.cell) {
                label if label.is_empty() => String::new(),
                label => format!(", cell {label}"),
            }
        );
        for (metric, value) in METRICS.iter().zip(&row.values) {
            if value.is_nan() {
                continue;
            }
            match metric.kind {
                Kind::Count => println!("  {:<24} {value:>12}", metric.name),
                Kind::Real => println!("  {:<24} {value:>12.6}", metric.name),
            }
        }
    }
    Ok(())
}
