//! Evaluation: what a map is scored against, and the scores.
//!
//! Owns the ground truth ([`ground_truth`]: the scene voxelised at the map's
//! resolution, a cell occupied when its box meets a solid), the observable
//! mask ([`observable`]: the cells some true beam could have seen, from the
//! scans' `ScanTruth`), and the scores ([`scores`]: precision, recall, F1,
//! false-free rate, Brier, log-loss, ROC AUC; docs/math.md §7). It takes the
//! scene and the truth, never an experiment; `experiment::study::metrics` turns its
//! `MapScores` into the columns of runs.csv.
//!
//! ```no_run
//! use sigmap::eval::{ground_truth::voxelise, scores::score_map};
//! use sigmap::sim::scene::Scene;
//! let scene = Scene::load("scenes/tabletop.toml".as_ref())?;
//! let truth = voxelise(&scene, 0.02);
//! let observable = Default::default(); // eval::observable::observable_cells(..)
//! let scores = score_map(&truth, &truth, &observable);
//! # Ok::<(), sigmap::Error>(())
//! ```

pub mod ground_truth;
pub mod observable;
pub mod scores;
