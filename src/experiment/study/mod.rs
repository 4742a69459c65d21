//! Managing a study: the experiment file and its sweeps (`config`), its
//! methods (`run_method`), the metrics table (`metrics`), what the runs
//! conclude (`summary`), batch runs with resume, shards and merge (`batch`,
//! `journal`), SLURM (`cluster`) and the regression gate (`regress`).

pub mod batch;
pub mod cluster;
pub mod config;
pub mod journal;
pub mod merge;
pub mod metrics;
pub mod regress;
pub mod run_method;
pub mod summary;
