//! What a study writes for people and other tools: scan files
//! (`scan_files`), the export for other mappers (`export`), the one-page
//! report (`report`) and the results folder's README.md (`folder_readme`). The charts are in [`super::charts`].

pub mod export;
pub mod folder_readme;
pub mod report;
pub mod scan_files;
pub mod wrong_cells;

/// `n` seeds, in words: "1 seed", "3 seeds".
pub fn seeds(n: usize) -> String {
    if n == 1 {
        "1 seed".into()
    } else {
        format!("{n} seeds")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn one_seed_is_singular() {
        assert_eq!(super::seeds(1), "1 seed");
        assert_eq!(super::seeds(0), "0 seeds");
        assert_eq!(super::seeds(40), "40 seeds");
    }
}
