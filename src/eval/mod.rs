//! Evaluation: the ground truth the maps are scored against.

pub mod ground_truth;
pub mod observable;
pub mod scores;
