//! `sigmap map`: simulate an experiment's run and build its map with one
//! method; write the OctoMap file; optionally export the rays for OctoMap.

use super::{progress_bar, with_threads, MapArgs};
use crate::error::{Error, Result};
use crate::experiment::model::{build_map, MapperView};
use crate::experiment::{self, write_rays, Experiment};
use crate::mapping::octomap_io::write_octree;
use std::path::PathBuf;
use std::time::Instant;

/// `sigmap map`.
pub(crate) fn run(args: MapArgs) -> Result<()> {
    let experiment = Experiment::load(&args.experiment)?;
    let resolution = args.resolution.unwrap_or(experiment.resolution);
    if !(resolution.is_finite() && (0.001..=1.0).contains(&resolution)) {
        return Err(Error::Usage(
            "--resolution must be between 0.001 and 1 m".into(),
        ));
    }
    let seed = args.run.seed.unwrap_or(experiment.seed);
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("results")
            .join(&experiment.name)
            .join(format!("map_{}.bt", args.method))
    });
    if !matches!(out.extension().and_then(|e| e.to_str()), Some("bt" | "ot")) {
        return Err(Error::input(&out, "the map file must end in .bt or .ot"));
    }
    let bar = progress_bar(experiment.viewpoints.len(), "simulating", args.run.quiet);
    let run = with_threads(args.run.threads, || {
        experiment::simulate(&experiment, seed, |d| bar.set_position(d as u64))
    })??;
    bar.finish_and_clear();
    let view = MapperView::of(&experiment);
    if let Some(path) = &args.export_rays {
        write_rays(path, &view, &run.scans)?;
    }
    let start = Instant::now();
    let tree = with_threads(args.run.threads, || {
        build_map(
            &view,
            &run.scans,
            args.method,
            resolution,
            &crate::geometry::Vector3::zeros(),
        )
    })??;
    let seconds = start.elapsed().as_secs_f64();
    write_octree(&out, &tree, experiment.map.clamp())?;
    let stats = tree.stats();
    let beams: usize = run.scans.iter().map(|s| s.measurements.len()).sum();
    if !args.run.quiet {
        eprintln!(
            "{} map at {} m: {} nodes ({} leaves), {} bytes ({:.1} per leaf; OctoMap's layout: {:.1}); \
             {beams} beams in {seconds:.2} s ({:.2} M beams/s); wrote {}",
            args.method,
            resolution,
            stats.nodes,
            stats.leaves,
            stats.bytes,
            stats.bytes as f64 / stats.leaves.max(1) as f64,
            (16 * stats.nodes + 64 * stats.inner) as f64 / stats.leaves.max(1) as f64,
            beams as f64 / seconds / 1e6,
            out.display()
        );
    }
    Ok(())
}
