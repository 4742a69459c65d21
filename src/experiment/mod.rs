//! Experiments: from an experiment file to scored runs and their files.
//!
//! Owns the experiment file and its sweeps ([`Experiment`], `config`), one
//! simulated run ([`simulate`]: the truth draw and a scan per viewpoint;
//! its maps are built by [`crate::mapping::build_map`] from
//! [`Experiment::mapper_view`] and the scans, never the truth), one scored run
//! ([`runner`]), the metrics table ([`metrics`]), batch runs with resume,
//! shards and merge ([`batch`], [`journal`]), SLURM submission ([`cluster`]),
//! the regression gate ([`regress`]), scan files, and charts ([`plots`],
//! [`figures`]). Each `sigmap` command is a thin adapter over one of these.
//!
//! ```no_run
//! use sigmap::experiment::{runner, simulate, Experiment};
//! use sigmap::mapping::{build_map, Method};
//! let experiment = Experiment::load("experiments/quickstart.toml".as_ref())?;
//! let run = simulate(&experiment, 1, |_viewpoints_done| {})?;
//! let view = experiment.mapper_view();
//! let map = build_map(&view, &run.scans, Method::Unscented, 0.01, &experiment.map_offset(1))?;
//! // Or everything `sigmap run` does for one seed: every method, scored.
//! let truth = runner::ground_truth(&experiment, 1);
//! let (rows, _timings, _maps) = runner::run_seed(&experiment, &truth, 1)?;
//! println!("F1 {}", rows[0].get("f1"));
//! # Ok::<(), sigmap::Error>(())
//! ```

pub mod batch;
pub mod cluster;
mod config;
pub mod export;
pub mod external;
pub mod figures;
pub mod journal;
pub mod metrics;
pub mod plots;
pub mod recorded;
pub mod regress;
pub mod report;
pub mod run_method;
pub mod runner;
mod scan_files;
pub mod scoring;
mod simulate;
pub mod summary;

pub use config::{Experiment, Overrides, SweepAxis, SweepValue, Viewpoint};
pub use run_method::RunMethod;
pub use scan_files::{chain_file, default_scan_dir, read_ply, write_ply, write_rays, write_scans};
pub use simulate::{simulate, RunTruth, SimulatedRun};
