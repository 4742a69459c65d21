//! What a study writes for people and other tools: scan files
//! (`scan_files`), the export for other mappers (`export`), the one-page
//! report (`report`) and the results folder's README.md (`folder_readme`). The charts are in [`super::charts`].

pub mod export;
pub mod folder_readme;
pub mod report;
pub mod scan_files;
pub mod wrong_cells;
