//! Running one run: simulating it (`simulate`), building and scoring every
//! method's map on its scans (`runner`), running an external mapper on them
//! (`external`), the scoring references (`consensus_truth`,
//! `registration_belief`), mapping scans recorded elsewhere (`recorded`) and scoring
//! maps built elsewhere (`scoring`).

pub mod consensus_truth;
pub mod depth_folder;
pub mod external;
pub mod placement;
pub mod recorded;
pub mod registration_belief;
pub mod runner;
pub mod scoring;
pub mod simulate;
