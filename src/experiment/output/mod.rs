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

/// What the maps are told of the profile's errors, for people: the
/// `[believed]` factors (docs/math.md §6.7), and whether a sweep axis
/// changes them from cell to cell.
pub fn told_errors(experiment: &super::Experiment) -> String {
    let believed = experiment.believed();
    let swept = experiment
        .sweep()
        .iter()
        .any(|axis| axis.field.starts_with("experiment.believed."));
    let whose = match believed.profile {
        Some(_) => format!(
            "those of the profile '{}' (the simulator draws those of '{}')",
            experiment.believed_profile().name,
            experiment.profile().name
        ),
        None => "the profile's, which the simulator draws".to_string(),
    };
    let base = if believed.is_calibrated() {
        "the profile's, as the simulator draws them".to_string()
    } else if believed.pose_sigma == 1.0 && believed.sensor_sigma == 1.0 {
        format!("{whose} ([believed], docs/math.md §6.7)")
    } else {
        format!(
            "pose σ × {}, range σ × {} of {whose} ([believed], docs/math.md §6.7)",
            believed.pose_sigma, believed.sensor_sigma
        )
    };
    if swept {
        format!("{base}; a sweep axis sets them per cell (the cell's label)")
    } else {
        base
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
