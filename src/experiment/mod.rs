//! Experiments: the configuration schema, the simulated runs, and their files.

pub mod batch;
pub mod cluster;
mod config;
pub mod figures;
pub mod journal;
pub mod metrics;
pub mod model;
pub mod plots;
pub mod regress;
pub mod runner;
mod scan_files;
mod simulate;

pub use config::{Experiment, SweepAxis, SweepValue, Viewpoint};
pub use scan_files::{chain_file, default_scan_dir, read_ply, write_ply, write_rays, write_scans};
pub use simulate::{simulate, RunTruth, SimulatedRun};
