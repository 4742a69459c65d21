//! What a study writes for people and other tools: scan files
//! (`scan_files`), the export for other mappers (`export`) and the one-page
//! report (`report`). The charts are in [`super::charts`].

pub mod export;
pub mod report;
pub mod scan_files;
