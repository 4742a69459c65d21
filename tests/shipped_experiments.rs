//! Every shipped experiment loads with each of its sweep cells applied (a
//! broken file would otherwise surface only when a user runs it), and the
//! table of shipped experiments in docs/results.md names exactly the files in
//! `experiments/`.

use sigmap::experiment::Experiment;
use std::collections::BTreeSet;
use std::path::Path;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The stems of `experiments/*.toml` (the profiles live in a subfolder).
fn shipped() -> BTreeSet<String> {
    std::fs::read_dir(Path::new(ROOT).join("experiments"))
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|e| e == "toml"))
        .map(|path| path.file_stem().unwrap().to_string_lossy().into_owned())
        .collect()
}

#[test]
fn every_shipped_experiment_loads_in_every_sweep_cell() {
    let names = shipped();
    assert!(names.len() >= 10, "{names:?}");
    for name in &names {
        let path = Path::new(ROOT).join(format!("experiments/{name}.toml"));
        let base = Experiment::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        for cell in base.cells() {
            Experiment::load_cell(&path, &cell)
                .unwrap_or_else(|e| panic!("{name}, cell {cell:?}: {e}"));
        }
    }
}

#[test]
fn the_results_page_lists_every_shipped_experiment() {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("docs/results.md")).unwrap();
    let start = readme
        .find("## Shipped experiments")
        .expect("docs/results.md has a table of shipped experiments");
    // The table: the rows up to the first blank line after its header.
    let table = readme[start..]
        .lines()
        .skip_while(|line| !line.starts_with('|'))
        .take_while(|line| line.starts_with('|'));
    let mut listed = BTreeSet::new();
    for row in table {
        let first = row.split('|').nth(1).unwrap_or_default();
        // A row may name several experiments: `paper`, `paper_shelf`, ...
        for name in first.split('`').skip(1).step_by(2) {
            listed.insert(name.to_string());
        }
    }
    assert_eq!(
        listed,
        shipped(),
        "docs/results.md table against experiments/*.toml"
    );
}

/// Every shipped error profile loads, also one that no shipped experiment
/// uses (a user's starting point).
#[test]
fn every_shipped_profile_loads() {
    let profiles: Vec<_> = std::fs::read_dir(Path::new(ROOT).join("experiments/profiles"))
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|e| e == "toml"))
        .collect();
    assert!(profiles.len() >= 8, "{profiles:?}");
    for path in profiles {
        sigmap::sim::profile::ErrorProfile::load(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
}
