//! sigmap: find out, with numbers, whether an occupancy map can be trusted.
//!
//! A simulated 6-DOF arm carries a laser range scanner through a workcell of
//! triangle meshes; sigmap injects calibrated Gaussian errors, propagates the
//! uncertainty through `X_s = T_sw⁻¹ T_rw T_cr X_c` into the scene frame, builds
//! a probabilistic octree and scores it against the ground truth (Payeur,
//! IMTC 2002; the math is in docs/math.md).
//!
//! Modules by concept (docs/architecture.md: what each owns and may import):
//! [`geometry`] (poses, rpy rotations), [`uncertainty`] (uncertain transforms,
//! the propagators, consistency statistics), [`sim`] (scene, robot, scanner,
//! error profiles, truth draw), [`mapping`] (local grids, the cell model, the
//! octree, OctoMap's update and files; it never sees the truth), [`eval`]
//! (ground truth, observable mask, scores), [`experiment`] (configuration,
//! map building behind a truth-free view, the metrics table, batch runs with
//! resume, shards, SLURM, summaries, SVG charts), [`files`]
//! (staged output that never deletes what sigmap did not write), [`error`]
//! (one-line errors and exit codes), [`cli`] (the `sigmap` command: thin
//! adapters over the library).

pub mod cli;
pub mod error;
pub mod eval;
pub mod experiment;
pub mod files;
pub mod geometry;
pub mod heap;
pub mod mapping;
pub mod sim;
pub mod uncertainty;

pub use error::{Error, Result};
