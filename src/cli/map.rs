//! `sigmap map`: simulate an experiment's run and build its map with one
//! method; write the OctoMap file; optionally export the rays for OctoMap.
//! With `--scans`, map a recorded ScanGraph instead (`experiment::run::recorded`).

use super::{progress_bar, resolution_arg, spinner, with_threads, MapArgs};
use crate::error::{Error, Result};
use crate::eval::ground_truth::KeyBox;
use crate::experiment::run::recorded::{map_recorded, read_scans, RecordedOptions};
use crate::experiment::run::runner::{observable, truth_reference};
use crate::experiment::{self, write_rays, Experiment, Overrides};
use crate::mapping::build_map;
use crate::mapping::method::truth_from_scans;
use crate::mapping::octomap_io::{check_octree_path, write_octree};
use crate::mapping::octree::Octree;
use crate::mapping::settings::{MapProbabilities, MapSettings, OpdfDefaults};
use crate::sim::profile::ErrorProfile;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `sigmap map`.
pub(crate) fn run(args: MapArgs) -> Result<()> {
    let Some(experiment) = &args.experiment else {
        return run_recorded(&args);
    };
    if args.profile.is_some() || args.max_range.is_some() || args.angular_step.is_some() {
        // clap drops `requires = "scans"` once --scans conflicts with the experiment.
        return Err(Error::Usage(
            "--profile, --max-range and --angular-step are for --scans (recorded scans); \
             an experiment's scans take them from the experiment file"
                .into(),
        ));
    }
    let experiment = load_experiment(experiment, &args)?;
    let (resolution, seed) = (experiment.resolution(), experiment.seed());
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("results")
            .join(experiment.name())
            .join(format!("map_{}.bt", args.method))
    });
    check_octree_path(&out)?;
    if args.observed && !args.method.is_truth() {
        return Err(Error::Usage(format!(
            "--observed is for the truth references (registered_truth, consensus_truth, \
             registration_belief); {} maps what its scans see",
            args.method
        )));
    }
    if args.method.is_truth() && !args.observed {
        // The whole workspace's truth, as the registration (and the scans) place it.
        let scene = experiment.scene();
        scene.check_truth_region(&scene.workspace, resolution, "the whole workspace")?;
    }
    print_notes(&args, &experiment);
    let bar = progress_bar(experiment.viewpoints().len(), "simulating", args.run.quiet);
    let run = with_threads(args.run.threads, || {
        experiment::simulate(&experiment, seed, |d| bar.set_position(d as u64))
    })??;
    bar.finish_and_clear();
    let view = experiment.mapper_view();
    // The run's map frame (the scene shifted by the seed's grid offset), as
    // `sigmap run`, `export` and `score` have it.
    let offset = experiment.map_offset(seed);
    if let Some(path) = &args.export_rays {
        write_rays(path, &view, &run.scans, &offset)?;
    }
    let start = Instant::now();
    // A truth over the whole workspace, or over the box of cells the scans
    // observe (as `sigmap run` has it).
    let (region, over) = if args.observed {
        let cells = observable(&experiment, &run.truth.scans, &offset);
        (KeyBox::spanning(cells), "the observed cells")
    } else {
        (KeyBox::ALL, "the whole workspace")
    };
    let computing = args.method.is_truth().then(|| {
        let what = format!("{} over {over}", args.method);
        spinner(&what, args.run.quiet)
    });
    let tree = match truth_reference(args.method, &experiment, &run, &offset, &region) {
        Some(tree) => tree,
        None => with_threads(args.run.threads, || {
            build_map(&view, &run.scans, args.method, resolution, &offset)
        })??,
    };
    if let Some(spinner) = computing {
        spinner.finish_and_clear();
    }
    let seconds = start.elapsed().as_secs_f64();
    write_octree(&out, &tree, experiment.map().clamp())?;
    let beams: usize = run.scans.iter().map(|s| s.measurements.len()).sum();
    if !args.run.quiet {
        report(&args, resolution, &tree, beams, seconds, &out);
    }
    Ok(())
}

/// The experiment at `path` with the command line's values in place of the
/// file's, checked as the file's are (the resolution's range, the clearing
/// bound of the method, the sample budget), before the simulation; an
/// error a flag's value caused names the flag.
fn load_experiment(path: &Path, args: &MapArgs) -> Result<Experiment> {
    let overrides = Overrides {
        resolution: args.resolution,
        seed: args.run.seed,
        beam_pooling: args.beam_pooling,
        interpolate_beams: args.interpolate_beams.as_deref().map(|on| on == "on"),
        risk: args.risk.map(|r| r.0),
        methods: Some(vec![args.method]),
        grid_offset: None,
    };
    let cell = Experiment::cell_values(path, args.cell).map_err(super::cell_flag)?;
    Experiment::load_with(path, &cell, &overrides).map_err(|e| {
        // The library says which value is wrong; name the flag that gave it.
        let given = [
            (
                "interpolate_beams",
                "--interpolate-beams",
                args.interpolate_beams.is_some(),
            ),
            ("resolution", "--resolution", args.resolution.is_some()),
            (
                "beam_pooling",
                "--beam-pooling",
                args.beam_pooling.is_some(),
            ),
            ("risk", "--risk", args.risk.is_some()),
        ];
        // A value's error leads with its key (`risk = 0.7 must be …`); one
        // that only names it (TOML's list of known fields) is the file's.
        let led_by =
            |key: &str| matches!(&e, Error::Input { message, .. } if message.starts_with(key));
        match given.iter().find(|(key, _, on)| *on && led_by(key)) {
            Some((_, flag, _)) => e.context(format!("{flag}: ")),
            None => e,
        }
    })
}

/// What the user should know before the run: the input files' notes,
/// which sweep cell is mapped, and whether the default samples were left
/// off.
fn print_notes(args: &MapArgs, experiment: &Experiment) {
    super::print_notes(experiment.notes(), args.run.quiet);
    if args.cell.is_none() && !experiment.sweep().is_empty() && !args.run.quiet {
        let cells = experiment.cells();
        eprintln!(
            "note: the experiment sweeps {} cells and this maps the base experiment (the file's \
             own values); --cell K maps sweep cell K (0 to {}, in the order of summary.csv), as \
             `sigmap run` does",
            cells.len(),
            cells.len() - 1
        );
    }
    if let Some(note) =
        super::samples_note(experiment).filter(|_| args.method.builds_grids() && !args.run.quiet)
    {
        eprintln!("{note}");
    }
}

/// `sigmap map --scans GRAPH --profile PROFILE`.
fn run_recorded(args: &MapArgs) -> Result<()> {
    let scans = args.scans.as_ref().expect("clap: experiment or --scans");
    let profile = args
        .profile
        .as_ref()
        .expect("clap: --scans requires --profile");
    let Some(out) = &args.out else {
        return Err(Error::Usage(
            "--scans needs --out MAP.bt (where to write the map)".into(),
        ));
    };
    check_octree_path(out)?;
    if args.method.is_truth() {
        return Err(Error::Usage(truth_from_scans(args.method)));
    }
    if args.run.seed.is_some() {
        return Err(Error::Usage(
            "--seed has no meaning with --scans: recorded scans are not simulated".into(),
        ));
    }
    let resolution = resolution_arg(args.resolution.unwrap_or(0.1))?;
    if let Some(m) = args.max_range {
        if !(m.is_finite() && m > 0.0) {
            return Err(Error::Usage(format!(
                "--max-range {m}: must be a positive number of metres"
            )));
        }
    }
    let angular_step = match args.angular_step {
        Some(deg) if !(deg.is_finite() && deg > 0.0 && deg <= 10.0) => {
            return Err(Error::Usage(format!(
                "--angular-step {deg}: must be between 0 and 10 degrees"
            )))
        }
        step => step.map(f64::to_radians),
    };
    let profile = ErrorProfile::load(profile)?;
    let depth = args.depth.options();
    let (nodes, notes) = read_scans(scans, &depth)?;
    super::print_notes(&notes, args.run.quiet);
    // Depth images bin at their central pixel's angle, not at the median.
    let angular_step = angular_step.or_else(|| scans.is_dir().then(|| depth.camera.angular_step()));
    let options = RecordedOptions {
        method: args.method,
        resolution,
        max_range: args.max_range,
        angular_step,
    };
    let beam_pooling = args.beam_pooling.unwrap_or_default();
    let risk = args.risk.map_or(OpdfDefaults::MEASURED.risk, |r| r.0);
    let mut settings = MapSettings::new(&MapProbabilities::default(), risk, beam_pooling)
        .map_err(|e| Error::Usage(format!("--risk: {e}")))?;
    settings.interpolate_beams = args.interpolate_beams.as_deref() == Some("on");
    let bar = progress_bar(nodes.len(), "mapping scans", args.run.quiet);
    let start = Instant::now();
    let tree = with_threads(args.run.threads, || {
        map_recorded(&nodes, &profile, &settings, &options, |k| {
            bar.set_position(k as u64);
        })
    })??;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    write_octree(out, &tree, settings.clamp())?;
    if !args.run.quiet {
        let points: usize = nodes.iter().map(|n| n.points.len()).sum();
        eprintln!("{} scans from {}", nodes.len(), scans.display());
        report(args, resolution, &tree, points, seconds, out);
    }
    Ok(())
}

/// Prints what was built.
fn report(args: &MapArgs, resolution: f64, tree: &Octree, beams: usize, seconds: f64, out: &Path) {
    let stats = tree.stats();
    let rate = if args.method.is_truth() {
        // Voxelised from the truth, not built from the beams.
        format!("voxelised in {seconds:.3} s")
    } else {
        format!(
            "{beams} beams in {seconds:.3} s ({:.3} M beams/s)",
            beams as f64 / seconds / 1e6
        )
    };
    eprintln!(
        "{} map at {} m: {} nodes ({} leaves), {} bytes ({:.1} per leaf; OctoMap's layout: {:.1}); \
         {rate}; wrote {}",
        args.method,
        resolution,
        stats.nodes,
        stats.leaves,
        stats.bytes,
        stats.bytes as f64 / stats.leaves.max(1) as f64,
        (16 * stats.nodes + 64 * stats.inner) as f64 / stats.leaves.max(1) as f64,
        out.display()
    );
}
