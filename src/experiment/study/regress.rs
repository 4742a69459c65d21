//! The regression gate: a summary against a committed baseline, metric by
//! metric, with per-metric tolerances.

use crate::error::{Error, Result};
use crate::experiment::study::metrics::Tolerance;
use crate::experiment::study::summary::SummaryRow;
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
}
