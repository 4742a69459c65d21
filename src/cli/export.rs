//! `sigmap export`: one run's scans for another mapper (`experiment::output::export`).

use super::{progress_bar, with_threads, ExportArgs};
use crate::error::Result;
use crate::experiment::output::export::{graph2tree_command, write_export, MapFrame};
use crate::experiment::{self, Experiment};
use std::path::PathBuf;

/// `sigmap export`.
pub(crate) fn run(args: ExportArgs) -> Result<()> {
    let experiment =
        Experiment::load_cell_index(&args.experiment, args.cell).map_err(super::cell_flag)?;
    super::print_notes(experiment.notes(), args.run.quiet);
    let seed = args.run.seed.unwrap_or(experiment.seed());
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("results")
            .join(experiment.name())
            .join("export")
    });
    let bar = progress_bar(experiment.viewpoints().len(), "simulating", args.run.quiet);
    let run = with_threads(args.run.threads, || {
        experiment::simulate(&experiment, seed, |d| bar.set_position(d as u64))
    })??;
    bar.finish_and_clear();
    let label = Experiment::cell_label(experiment.cell());
    let what = format!(
        "experiment '{}', seed {seed}{}",
        experiment.name(),
        if label.is_empty() {
            String::new()
        } else {
            format!(", cell {label}")
        }
    );
    let view = experiment.mapper_view();
    let offset = experiment.map_offset(seed);
    write_export(
        &out,
        &view,
        &run.scans,
        &MapFrame {
            resolution: experiment.resolution(),
            offset: &offset,
            camera: experiment.scanner().camera.as_ref(),
        },
        &what,
    )?;
    if !args.run.quiet {
        eprintln!(
            "wrote {} scans of {what} to {} (scans.graph, vp_NNN.ply, poses.txt, README.txt{})",
            run.scans.len(),
            out.display(),
            if experiment.scanner().camera.is_some() {
                ", the depth images in depth/ and depth.txt"
            } else {
                ""
            }
        );
        println!(
            "{}",
            graph2tree_command(
                &out,
                experiment.resolution(),
                experiment.scanner().max_range
            )
        );
        eprintln!(
            "then score map.bt.ot, the full tree graph2tree writes beside map.bt (the .bt \
             drops the log-odds)"
        );
    }
    Ok(())
}
