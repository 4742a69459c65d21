//! The regression gate: a summary against a committed baseline, metric by
//! metric, with per-metric tolerances.

use crate::error::{Error, Result};
use crate::experiment::study::metrics::Tolerance;
use crate::experiment::study::summary::SummaryRow;
use crate::uncertainty::consistency::Consistency;
use std::collections::BTreeSet;
use std::path::Path;

/// The default allowed drift of a metric's mean, from the metrics table
/// (absolute 0.01 for scores in [0, 1], 5% of the baseline for ANEES and
/// log-loss); 0.01 for a metric the table does not know.
pub fn default_tolerance(metric: &str, baseline: f64) -> f64 {
    match crate::experiment::study::metrics::metric(metric).map(|m| m.tolerance) {
        Some(Tolerance::Relative(fraction)) => fraction * baseline.abs(),
        Some(Tolerance::Absolute(drift)) => drift,
        Some(Tolerance::NotSummarised) | None => 0.01,
    }
}

/// One compared (method, metric).
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// The sweep cell.
    pub cell: String,
    /// The method.
    pub method: String,
    /// The metric.
    pub metric: String,
    /// Baseline mean.
    pub baseline: f64,
    /// Current mean (NaN when missing).
    pub current: f64,
    /// Allowed drift.
    pub tolerance: f64,
}

impl Comparison {
    /// The drift exceeds the tolerance (either way), or the metric vanished or
    /// turned non-finite.
    pub fn regressed(&self) -> bool {
        if self.baseline.is_nan() {
            return false;
        }
        !self.current.is_finite() || (self.current - self.baseline).abs() > self.tolerance
    }
}

/// Compares every (method, metric) of the baseline with the current summary.
/// `overrides` maps a metric to its tolerance.
pub fn compare(
    current: &[SummaryRow],
    baseline: &[SummaryRow],
    overrides: &[(String, f64)],
) -> Vec<Comparison> {
    baseline
        .iter()
        .map(|b| {
            let current = current
                .iter()
                .find(|c| c.cell == b.cell && c.method == b.method && c.metric == b.metric)
                .map_or(f64::NAN, |c| c.mean);
            let tolerance = overrides
                .iter()
                .find(|(m, _)| *m == b.metric)
                .map_or_else(|| default_tolerance(&b.metric, b.mean), |(_, t)| *t);
            Comparison {
                cell: b.cell.clone(),
                method: b.method.clone(),
                metric: b.metric.clone(),
                baseline: b.mean,
                current,
                tolerance,
            }
        })
        .collect()
}

/// The per-point consistency check of one method in one cell: its mean
/// NEES of one point a run over the seeds (`nees_point`) against the 95%
/// band honest covariances give that mean (docs/math.md §6.2, §6.6).
#[derive(Clone, Debug, PartialEq)]
pub struct ConsistencyCheck {
    /// The sweep cell.
    pub cell: String,
    /// Seeds with a finite value.
    pub n: usize,
    /// The mean (NaN when no seed has one).
    pub mean: f64,
    /// The band.
    pub band: (f64, f64),
    /// Where the mean lies; `None` without a finite mean.
    pub verdict: Option<Consistency>,
}

impl ConsistencyCheck {
    /// Outside the band, or nothing to judge.
    pub fn failed(&self) -> bool {
        self.verdict != Some(Consistency::Consistent)
    }
}

/// The consistency check of `method` in every cell of `summary`, or why
/// there is none: the summary has no finite `nees_point` of that method
/// (it propagates no covariance, or is not in the summary).
pub fn check_consistency(
    summary: &[SummaryRow],
    method: &str,
) -> std::result::Result<Vec<ConsistencyCheck>, String> {
    let checks: Vec<ConsistencyCheck> = summary
        .iter()
        .filter(|r| r.method == method && r.metric == "nees_point")
        .map(|r| {
            let judged = r.n > 0 && r.mean.is_finite();
            let (verdict, band) = Consistency::of_mean_nees(r.mean, r.n);
            ConsistencyCheck {
                cell: r.cell.clone(),
                n: r.n,
                mean: r.mean,
                band,
                verdict: judged.then_some(verdict),
            }
        })
        .collect();
    if !checks.iter().any(|c| c.verdict.is_some()) {
        let methods: BTreeSet<&str> = summary
            .iter()
            .filter(|r| r.metric == "nees_point" && r.n > 0 && r.mean.is_finite())
            .map(|r| r.method.as_str())
            .collect();
        return Err(format!(
            "--consistent {method}: the summary has no nees_point of '{method}' (the methods \
             that propagate covariances here: {})",
            if methods.is_empty() {
                "none".to_string()
            } else {
                methods.into_iter().collect::<Vec<_>>().join(", ")
            }
        ));
    }
    Ok(checks)
}

/// The rows of a `summary.csv`: at least one, none repeated.
pub fn read_summary(path: &Path) -> Result<Vec<SummaryRow>> {
    if !path.is_file() {
        return Err(Error::input(
            path,
            if path.exists() {
                "is not a file"
            } else {
                "file not found"
            },
        ));
    }
    let not_summary = |e: &dyn std::fmt::Display| {
        Error::input(
            path,
            format!("is not a summary.csv written by `sigmap run` ({e})"),
        )
    };
    let mut reader = csv::Reader::from_path(path).map_err(|e| not_summary(&e))?;
    let rows: Vec<SummaryRow> = reader
        .deserialize()
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| not_summary(&e))?;
    if rows.is_empty() {
        return Err(Error::input(path, "holds no rows: nothing to compare"));
    }
    let mut seen = BTreeSet::new();
    if let Some(r) = rows
        .iter()
        .find(|r| !seen.insert((&r.cell, &r.method, &r.metric)))
    {
        return Err(Error::input(
            path,
            format!(
                "lists method '{}', metric '{}' of cell '{}' twice",
                r.method, r.metric, r.cell
            ),
        ));
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: &str, metric: &str, mean: f64) -> SummaryRow {
        SummaryRow {
            cell: String::new(),
            method: method.into(),
            metric: metric.into(),
            n: 3,
            mean,
            ci95_low: mean,
            ci95_high: mean,
        }
    }

    #[test]
    fn drifts_past_the_tolerance_regress() {
        let baseline = vec![
            row("unscented", "f1", 0.80),
            row("unscented", "anees", 3.0),
            row("blind", "f1", 0.7),
        ];
        let same = compare(&baseline, &baseline, &[]);
        assert!(same.iter().all(|c| !c.regressed()));
        let current = vec![row("unscented", "f1", 0.78), row("unscented", "anees", 3.1)];
        let result = compare(&current, &baseline, &[]);
        assert!(result[0].regressed(), "f1 fell by 0.02 > 0.01");
        assert!(!result[1].regressed(), "anees within 5%");
        assert!(result[2].regressed(), "a method that vanished regresses");
        let relaxed = compare(&current, &baseline, &[("f1".into(), 0.05)]);
        assert!(!relaxed[0].regressed());
    }

    /// Each cell's mean one-point NEES is judged against the band of its
    /// own seed count; a mean outside it, or no finite mean, fails; a method
    /// with no NEES is no check at all.
    #[test]
    fn the_consistency_check_judges_each_cell() {
        let mut rows = vec![
            row("unscented", "nees_point", 2.6),
            row("blind", "nees_point", 143.0),
            row("ray_update", "f1", 0.9),
            SummaryRow {
                n: 0,
                ..row("ray_update", "nees_point", f64::NAN)
            },
        ];
        rows.push(SummaryRow {
            cell: "a=2".into(),
            n: 40,
            ..row("unscented", "nees_point", 2.0)
        });
        rows.push(SummaryRow {
            cell: "a=3".into(),
            n: 0,
            ..row("unscented", "nees_point", f64::NAN)
        });
        let checks = check_consistency(&rows, "unscented").unwrap();
        let failed: Vec<_> = checks.iter().map(ConsistencyCheck::failed).collect();
        assert_eq!(failed, [false, true, true]);
        assert_eq!(checks[1].verdict, Some(Consistency::Conservative));
        assert!(
            (checks[1].band.0 - 2.289).abs() < 1e-3,
            "{:?}",
            checks[1].band
        );
        assert_eq!(checks[2].verdict, None);
        let blind = check_consistency(&rows, "blind").unwrap();
        assert_eq!(blind[0].verdict, Some(Consistency::OverConfident));
        for method in ["ray_update", "octomap"] {
            let message = check_consistency(&rows, method).unwrap_err();
            assert!(message.contains("here: blind, unscented"), "{message}");
        }
    }
}
