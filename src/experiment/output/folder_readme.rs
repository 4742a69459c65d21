//! The `README.md` of a results folder: what each file of `sigmap run`
//! holds and what each column means, so the folder explains itself.

use crate::error::Result;
use crate::experiment::study::metrics::{Better, METRICS};
use crate::experiment::Experiment;
use std::fmt::Write as _;
use std::path::Path;

/// How the README begins: a README.md of the folder that does not is not
/// sigmap's, and is left alone.
const TITLE: &str = "# Results of `";

/// Writes `README.md` into the results folder `out` of `experiment`
/// (staged, then renamed), unless the folder holds a README.md sigmap did
/// not write.
pub fn write_folder_readme(out: &Path, experiment: &Experiment) -> Result<()> {
    let path = out.join("README.md");
    if let Ok(existing) = std::fs::read_to_string(&path) {
        if !existing.starts_with(TITLE) {
            return Ok(());
        }
    }
    crate::files::write_file(&path, folder_readme(experiment).as_bytes())
}

/// The text of the folder's README.md.
pub fn folder_readme(experiment: &Experiment) -> String {
    let mut text = String::new();
    let methods: Vec<&str> = experiment
        .methods()
        .iter()
        .map(crate::experiment::RunMethod::as_str)
        .collect();
    let _ = writeln!(
        text,
        "{TITLE}{}`\n\n{}\n\nWritten by `sigmap run {}` (sigmap {}): {}, methods {}, \
         paired against `{}`; the errors the maps are told: {}. Rerunning resumes; `--fresh` \
         recomputes.\n",
        experiment.name(),
        experiment.description(),
        experiment.source().display(),
        env!("CARGO_PKG_VERSION"),
        super::count(experiment.seeds().len(), "seed"),
        methods.join(", "),
        experiment.reference(),
        super::told_errors(experiment)
    );
    text.push_str(FILES);
    text.push_str("\n## runs.csv columns\n\n| column | meaning | better |\n|---|---|---|\n");
    text.push_str(
        "| `cell` | the sweep cell, `field=value;...` (empty without a sweep) | |\n\
         | `seed` | the run's seed | |\n\
         | `method` | the method | |\n\
         | `resolution` | the map's finest voxel edge (m) | |\n",
    );
    for metric in &METRICS {
        let better = match metric.better {
            Better::Lower => "lower".to_string(),
            Better::Higher => "higher".to_string(),
            Better::Toward(t) => format!("nearer {t:.3}"),
            Better::Unranked => String::new(),
        };
        let _ = writeln!(text, "| `{}` | {} | {better} |", metric.name, metric.doc);
    }
    text.push_str(
        "\nAn empty or NaN value: the metric does not apply (a method that propagates \
         no covariance has no ANEES). docs/cli.md and docs/math.md §7 say more.\n",
    );
    text
}

const FILES: &str = "## Files\n\n\
| file | what it holds |\n\
|---|---|\n\
| `runs.csv` | one row per sweep cell, seed and method: every metric (columns below) |\n\
| `summary.csv` | per cell, method and metric: `n`, mean and 95% interval over the seeds (Student t, cut to the metric's range) |\n\
| `paired.csv` | per cell, method and metric, the method against the reference seed by seed: `n`, mean difference (method − reference), 95% interval, verdict `better` / `worse` / `within_noise` by the metric's direction; then each method against itself at a sweep axis's `reference` value (the row's `reference_cell`) |\n\
| `timings.csv` | seconds to simulate, model and score each run (they vary from run to run) |\n\
| `map_<method>.bt` | the first run's map of each method (OctoMap binary tree; open with octovis) |\n\
| `errors_<method>.ply` | the cells the first run's map of each method calls wrongly, the cells of its false-free (red) and false-occupied (orange) rates in runs.csv: a point cloud to open beside the map (CloudCompare, MeshLab) |\n\
| `slice.svg` | a horizontal slice through the first run's maps: each cell's class against the truth |\n\
| `coverage.svg`, `scores.svg`, `score_<metric>.svg`, `safety.svg` | the charts (the sweep charts with a sweep, the safety curve when ε is swept) |\n\
| `report.html` | all of the above on one self-contained page |\n\
| `run.toml` | the inputs' SHA-256 fingerprint (a rerun with other inputs is refused), each input file's hash, the shard, the external mappers' commands |\n";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_readme_names_every_file_and_every_column() {
        let experiment = Experiment::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/experiments/quickstart.toml"
        )))
        .unwrap();
        let text = folder_readme(&experiment);
        for file in [
            "runs.csv",
            "summary.csv",
            "paired.csv",
            "report.html",
            "slice.svg",
        ] {
            assert!(text.contains(&format!("`{file}`")), "{file}");
        }
        let header = crate::experiment::study::metrics::header();
        for column in header.split(',') {
            assert!(text.contains(&format!("| `{column}` |")), "column {column}");
        }
        assert!(text.contains("| `false_free_rate` |") && text.contains("| lower |"));
    }

    #[test]
    fn a_readme_sigmap_did_not_write_is_left_alone() {
        let experiment = Experiment::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/experiments/quickstart.toml"
        )))
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let readme = dir.path().join("README.md");
        std::fs::write(&readme, "# My notes\n").unwrap();
        write_folder_readme(dir.path(), &experiment).unwrap();
        assert_eq!(std::fs::read_to_string(&readme).unwrap(), "# My notes\n");
        std::fs::write(&readme, format!("{TITLE}old`\n")).unwrap();
        write_folder_readme(dir.path(), &experiment).unwrap();
        assert_eq!(
            std::fs::read_to_string(&readme).unwrap(),
            folder_readme(&experiment)
        );
    }
}
