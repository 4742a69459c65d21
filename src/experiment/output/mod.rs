//! What a study writes for people and other tools: scan files
//! (`scan_files`), the export for other mappers (`export`), the one-page
//! report (`report`) and the results folder's README.md (`folder_readme`). The charts are in [`super::charts`].

pub mod export;
pub mod folder_readme;
pub mod report;
pub mod scan_files;
pub mod wrong_cells;

/// `n` of `noun`, in words: "1 seed", "3 seeds".
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn one_is_singular() {
        assert_eq!(super::count(1, "seed"), "1 seed");
        assert_eq!(super::count(0, "seed"), "0 seeds");
        assert_eq!(super::count(40, "run"), "40 runs");
    }
}
