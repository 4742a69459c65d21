use super::*;
use crate::eval::scores::MapScores;
use crate::experiment::study::metrics::{Measured, COVERAGE_3D};
use crate::mapping::TreeStats;
use crate::uncertainty::consistency::expected_coverage;

fn seeds(values: &[f64]) -> Vec<(u64, f64)> {
    values
        .iter()
        .enumerate()
        .map(|(i, v)| (i as u64 + 1, *v))
        .collect()
}

#[test]
fn a_method_paired_with_itself_is_zero_within_noise() {
    let values = seeds(&[0.91, 0.87, 0.95, 0.90]);
    for better in [
        Better::Lower,
        Better::Higher,
        Better::Toward(3.0),
        Better::Toward(0.9),
    ] {
        let d = PairedDifference::of(&values, &values, better).unwrap();
        assert_eq!((d.n, d.mean, d.ci95), (4, 0.0, (0.0, 0.0)), "{better:?}");
        assert_eq!(d.verdict, Verdict::WithinNoise, "{better:?}");
    }
}

#[test]
fn the_student_t_interval_of_known_differences() {
    // Differences 1, 2, 3, 4, 5: mean 3, s² = 2.5, s/√5 = 0.707107,
    // t₀.₉₇₅,₄ = 2.776445 (tables): 3 ± 1.963243.
    let reference = seeds(&[10.0, 10.0, 10.0, 10.0, 10.0]);
    let method = seeds(&[11.0, 12.0, 13.0, 14.0, 15.0]);
    let d = PairedDifference::of(&method, &reference, Better::Higher).unwrap();
    assert_eq!(d.n, 5);
    assert!((d.mean - 3.0).abs() < 1e-12);
    assert!((d.ci95.0 - 1.036_757).abs() < 1e-6, "{:?}", d.ci95);
    assert!((d.ci95.1 - 4.963_243).abs() < 1e-6, "{:?}", d.ci95);
    assert_eq!(d.verdict, Verdict::Better);
    let d = PairedDifference::of(&method, &reference, Better::Lower).unwrap();
    assert_eq!(d.verdict, Verdict::Worse);
    // Differences −1, 1, 3 (mean 1, s = 2, t₀.₉₇₅,₂ = 4.302653): the
    // interval 1 ± 4.967 holds 0.
    let method = seeds(&[9.0, 11.0, 13.0]);
    let d = PairedDifference::of(&method, &reference, Better::Higher).unwrap();
    assert!((d.ci95.1 - d.mean - 4.302_653 * 2.0 / 3f64.sqrt()).abs() < 1e-5);
    assert_eq!(d.verdict, Verdict::WithinNoise);
}

#[test]
fn seeds_pair_by_seed_and_only_where_both_are_finite() {
    let method = vec![(3, 0.5), (1, 0.2), (2, f64::NAN), (7, 0.9)];
    let reference = vec![(1, 0.1), (2, 0.3), (3, 0.3), (4, 0.0)];
    let d = PairedDifference::of(&method, &reference, Better::Lower).unwrap();
    assert_eq!(d.n, 2, "seeds 1 and 3");
    assert!((d.mean - 0.15).abs() < 1e-12);
    // One pair: a mean, no interval, no verdict.
    let d = PairedDifference::of(&method[1..2], &reference, Better::Lower).unwrap();
    assert_eq!((d.n, d.verdict), (1, Verdict::WithinNoise));
    assert!(d.ci95.0.is_nan() && d.ci95.1.is_nan());
    assert!(PairedDifference::of(&method[3..], &reference, Better::Lower).is_none());
}

#[test]
fn a_target_metric_ranks_the_distance_to_its_target() {
    // ANEES: a method near 3 against an over-confident reference is better
    // although its values are lower; one as far below 3 as the reference is
    // above is within the noise of it.
    let reference = seeds(&[40.0, 55.0, 47.0, 52.0]);
    let near = seeds(&[3.2, 2.7, 3.4, 2.9]);
    let d = PairedDifference::of(&near, &reference, Better::Toward(3.0)).unwrap();
    assert!(d.ci95.1 < 0.0);
    assert_eq!(d.verdict, Verdict::Better);
    let d = PairedDifference::of(&reference, &near, Better::Toward(3.0)).unwrap();
    assert_eq!(d.verdict, Verdict::Worse);
    let mirrored = seeds(&[3.0 - 37.0, 3.0 - 52.0, 3.0 - 44.0, 3.0 - 49.0]);
    let d = PairedDifference::of(&mirrored, &reference, Better::Toward(3.0)).unwrap();
    assert!(d.mean < -80.0);
    assert_eq!(d.verdict, Verdict::WithinNoise);
}

#[test]
fn the_coverage_targets_are_the_chi_square_shares() {
    for (k, target) in COVERAGE_3D.iter().enumerate() {
        let expected = expected_coverage(k as f64 + 1.0, 3);
        assert!((expected - target).abs() < 1e-9, "{expected} vs {target}");
    }
}

fn row(cell: &str, seed: u64, method: &str, f1: f64, anees: f64) -> RunRow {
    let scores = MapScores::default();
    let stats = TreeStats {
        nodes: 1,
        leaves: 1,
        inner: 0,
        bytes: 8,
    };
    let measured = Measured {
        scores: &scores,
        consistency: None,
        nees_point: f64::NAN,
        stats: &stats,
    };
    let mut row = RunRow::new(cell.into(), seed, method, 0.01, &measured);
    for metric in METRICS.iter().filter(|m| m.summarised()) {
        row.set(metric.name, 0.5);
    }
    row.set("f1", f1);
    row.set("anees", anees);
    row
}

#[test]
fn paired_rows_cover_every_cell_method_and_metric_but_the_reference() {
    use crate::mapping::Method::*;
    let cells = vec!["a=1".to_string(), "a=2".to_string()];
    let mut rows = Vec::new();
    for cell in &cells {
        for seed in 1..=3 {
            let s = seed as f64;
            rows.push(row(cell, seed, "blind", 0.80 + 0.01 * s, 40.0));
            rows.push(row(
                cell,
                seed,
                "unscented",
                0.85 + 0.011 * s,
                3.0 + 0.1 * s,
            ));
            rows.push(row(cell, seed, "ray_update", 0.70 + 0.01 * s, f64::NAN));
        }
    }
    let methods = [Blind, Unscented, RayUpdate].map(RunMethod::Own);
    let out = paired(&rows, &cells, &methods, &RunMethod::Own(RayUpdate));
    let summarised = METRICS.iter().filter(|m| m.summarised()).count();
    // The ray update has no ANEES: no row pairs on it.
    assert_eq!(out.len(), 2 * 2 * (summarised - 1));
    assert!(out
        .iter()
        .all(|r| r.reference == "ray_update" && r.method != "ray_update"));
    assert!(out.iter().all(|r| r.metric != "anees"));
    let f1 = |cell: &str, method: &str| {
        out.iter()
            .find(|r| r.cell == cell && r.method == method && r.metric == "f1")
            .unwrap()
    };
    assert!((f1("a=2", "blind").mean - 0.10).abs() < 1e-12);
    assert_eq!(f1("a=2", "blind").verdict, Verdict::Better);
    assert_eq!(f1("a=1", "unscented").verdict, Verdict::Better);
    let equal = out.iter().find(|r| r.metric == "brier").unwrap();
    assert_eq!((equal.mean, equal.verdict), (0.0, Verdict::WithinNoise));
    // Against unscented, blind's ANEES is worse (farther from 3).
    let out = paired(&rows, &cells, &methods, &RunMethod::Own(Unscented));
    let anees = out
        .iter()
        .find(|r| r.method == "blind" && r.metric == "anees")
        .unwrap();
    assert_eq!((anees.n, anees.verdict), (3, Verdict::Worse));
}

#[test]
fn summary_intervals_stay_in_the_metric_range() {
    let cells = vec![String::new()];
    // F1 of 1, 1 and 0.9: the t interval reaches above 1; ANEES of 0.1,
    // 0.1, 9: below 0.
    let rows = vec![
        row("", 1, "blind", 1.0, 0.1),
        row("", 2, "blind", 1.0, 0.1),
        row("", 3, "blind", 0.9, 9.0),
    ];
    let summary = summarise(
        &rows,
        &cells,
        &[RunMethod::Own(crate::mapping::Method::Blind)],
    );
    let get = |metric: &str| summary.iter().find(|s| s.metric == metric).unwrap();
    let (mean, half) = mean_and_half_width(&[1.0, 1.0, 0.9]);
    assert!(mean + half > 1.0);
    assert_eq!(get("f1").ci95_high, 1.0);
    assert_eq!(get("f1").ci95_low, mean - half);
    assert_eq!(get("anees").ci95_low, 0.0);
    assert!(get("anees").ci95_high > 9.0);
}

#[test]
fn t_quantiles() {
    assert!(
        (crate::uncertainty::consistency::student_t_quantile(1.0, 0.975) - 12.706).abs() < 1e-3
    );
    assert!((crate::uncertainty::consistency::student_t_quantile(9.0, 0.975) - 2.262).abs() < 1e-3);
    assert!(
        (crate::uncertainty::consistency::student_t_quantile(1000.0, 0.975) - 1.962).abs() < 1e-3
    );
}

#[test]
fn an_axis_with_a_reference_pairs_each_method_with_itself_across_it() {
    use crate::mapping::Method::*;
    let number = |v: f64| SweepValue::Number(v);
    let text = |t: &str| SweepValue::Text(t.into());
    let axes = vec![
        SweepAxis {
            field: "pose_error_scale".into(),
            values: vec![number(0.0), number(2.0)],
            reference: None,
        },
        SweepAxis {
            field: "experiment.beam_pooling".into(),
            values: vec![text("off"), text("faces"), text("windows")],
            reference: Some(text("off")),
        },
    ];
    let cells: Vec<Vec<(String, SweepValue)>> = [0.0, 2.0]
        .iter()
        .flat_map(|&scale| {
            ["off", "faces", "windows"].map(|mode| {
                vec![
                    ("pose_error_scale".to_string(), number(scale)),
                    ("experiment.beam_pooling".to_string(), text(mode)),
                ]
            })
        })
        .collect();
    // F1 by cell: faces adds 0.05 + 0.01·seed to the unscented map and
    // nothing to the ray update; windows takes 0.02 from both.
    let mut rows = Vec::new();
    for cell in &cells {
        let label = Experiment::cell_label(cell);
        let mode = cell[1].1.to_string();
        for seed in 1..=4u64 {
            let s = seed as f64;
            let (unscented, ray) = match mode.as_str() {
                "faces" => (0.85 + 0.05 + 0.01 * s, 0.80 + 0.001 * s),
                "windows" => (0.83 + 0.001 * s, 0.78 + 0.001 * s),
                _ => (0.85 + 0.001 * s, 0.80 + 0.001 * s),
            };
            rows.push(row(&label, seed, "unscented", unscented, 3.0));
            rows.push(row(&label, seed, "ray_update", ray, f64::NAN));
        }
    }
    let methods = [Unscented, RayUpdate].map(RunMethod::Own);
    let out = paired_across_axes(&rows, &axes, &cells, &methods);
    // Two cells off the reference per scale, two methods; the ray update
    // has no ANEES.
    let summarised = METRICS.iter().filter(|m| m.summarised()).count();
    assert_eq!(out.len(), 2 * 2 * (2 * summarised - 1));
    assert!(out.iter().all(|r| !r.is_between_methods()));
    assert!(out.iter().all(|r| r.method == r.reference));
    let f1 = |cell: &str, method: &str| {
        out.iter()
            .find(|r| r.cell == cell && r.method == method && r.metric == "f1")
            .unwrap()
    };
    let faces = "pose_error_scale=2;experiment.beam_pooling=faces";
    let got = f1(faces, "unscented");
    assert_eq!(
        got.reference_cell,
        "pose_error_scale=2;experiment.beam_pooling=off"
    );
    // Differences 0.05 + 0.009·seed, seeds 1–4: mean 0.0725.
    assert!((got.mean - 0.0725).abs() < 1e-12, "{}", got.mean);
    assert_eq!(got.verdict, Verdict::Better);
    let got = f1(faces, "ray_update");
    assert!(got.mean.abs() < 1e-12);
    assert_eq!(got.verdict, Verdict::WithinNoise);
    let got = f1(
        "pose_error_scale=0;experiment.beam_pooling=windows",
        "ray_update",
    );
    assert!((got.mean + 0.02).abs() < 1e-12);
    assert_eq!(got.verdict, Verdict::Worse);
    // Without a reference value the axis gives no rows.
    let unreferenced: Vec<SweepAxis> = axes
        .iter()
        .cloned()
        .map(|a| SweepAxis {
            reference: None,
            ..a
        })
        .collect();
    assert!(paired_across_axes(&rows, &unreferenced, &cells, &methods).is_empty());
}
