//! The regression gate: a summary against a committed baseline, metric by
//! metric, with per-metric tolerances.

use super::runner::SummaryRow;

/// The default allowed drift of a metric's mean: absolute 0.01 for scores in
/// [0, 1], 5% of the baseline for ANEES and log-loss.
pub fn default_tolerance(metric: &str, baseline: f64) -> f64 {
    match metric {
        "anees" | "log_loss" => 0.05 * baseline.abs(),
        _ => 0.01,
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
