//! Experiments: from an experiment file to scored runs and their files, in
//! four layers (docs/architecture.md):
//!
//! - [`run`]: one run: [`simulate`] (the truth draw and a scan per
//!   viewpoint; its maps are built by [`crate::mapping::build_map`] from
//!   [`Experiment::mapper_view`] and the scans, never the truth),
//!   [`run::runner`] (every method scored), [`run::external`] (external
//!   mappers), [`run::recorded`] (scans recorded elsewhere) and
//!   [`run::scoring`] (maps built elsewhere);
//! - [`study`]: the experiment file ([`Experiment`]), its methods, the
//!   metrics table, summaries and paired comparisons, batch runs with
//!   resume, shards and merge, SLURM, the regression gate;
//! - [`output`]: scan files, the export for other mappers, report.html;
//! - [`charts`]: every chart.
//!
//! Each `sigmap` command is a thin adapter over one of these.
//!
//! ```no_run
//! use sigmap::experiment::run::runner;
//! use sigmap::experiment::{simulate, Experiment};
//! use sigmap::mapping::{build_map, Method};
//! let experiment = Experiment::load("experiments/quickstart.toml".as_ref())?;
//! let run = simulate(&experiment, 1, |_viewpoints_done| {})?;
//! let view = experiment.mapper_view();
//! let map = build_map(&view, &run.scans, Method::Unscented, 0.01, &experiment.map_offset(1))?;
//! // Or everything `sigmap run` does for one seed: every method, scored
//! // against the truth over the cells the run observed.
//! let outcome = runner::run_seed(&experiment, 1)?;
//! println!("F1 {}", outcome.rows[0].get("f1"));
//! # Ok::<(), sigmap::Error>(())
//! ```

pub mod charts;
pub mod output;
pub mod run;
pub mod study;

pub use output::scan_files::{
    chain_file, default_scan_dir, read_ply, write_ply, write_rays, write_scans,
};
pub use run::simulate::{simulate, RunTruth, SimulatedRun};
pub use study::config::{Experiment, Overrides, SweepAxis, SweepValue, Viewpoint};
pub use study::run_method::RunMethod;

/// The shipped quickstart experiment, loaded.
#[cfg(test)]
pub(crate) fn shipped_quickstart() -> Experiment {
    Experiment::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/quickstart.toml"
    )))
    .expect("experiments/quickstart.toml")
}

/// The shipped profile for recorded scans
/// (`experiments/profiles/collaborative_poses.toml`), loaded.
#[cfg(test)]
pub(crate) fn shipped_poses_profile() -> crate::sim::profile::ErrorProfile {
    crate::sim::profile::ErrorProfile::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/profiles/collaborative_poses.toml"
    )))
    .expect("experiments/profiles/collaborative_poses.toml")
}

/// The quickstart experiment's text with its relative paths made absolute,
/// so that a test may write an edited copy anywhere.
#[cfg(test)]
pub(crate) fn portable_quickstart() -> String {
    let root = env!("CARGO_MANIFEST_DIR");
    std::fs::read_to_string(format!("{root}/experiments/quickstart.toml"))
        .expect("experiments/quickstart.toml")
        .replace("\"../", &format!("\"{root}/"))
        .replace("\"profiles/", &format!("\"{root}/experiments/profiles/"))
}
