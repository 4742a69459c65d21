//! What a study concludes from its runs: per method the mean of each
//! summarised metric over the seeds (`summary.csv`), and per method the
//! per-seed differences against the reference method, and against itself at
//! a sweep axis's reference value (`paired.csv`), each with its 95% Student t
//! interval (docs/math.md §7.4).

use crate::experiment::study::config::{SweepAxis, SweepValue};
use crate::experiment::study::metrics::{Better, Metric, RunRow, METRICS};
use crate::experiment::{Experiment, RunMethod};
use crate::uncertainty::consistency::student_t_quantile;
use serde::{Deserialize, Serialize};

/// The mean of `values` and the half-width of its 95% Student t interval,
/// `t₀.₉₇₅,ₙ₋₁ · s/√n` (NaN for fewer than two values).
pub fn mean_and_half_width(values: &[f64]) -> (f64, f64) {
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return (mean, f64::NAN);
    }
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    (
        mean,
        student_t_quantile((n - 1) as f64, 0.975) * (var / n as f64).sqrt(),
    )
}

/// One row of `summary.csv`: a method's mean and 95% interval of a metric
/// over the seeds (Student t, cut to the metric's range; a single seed has
/// no interval).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SummaryRow {
    /// The sweep cell.
    pub cell: String,
    /// The method.
    pub method: String,
    /// The metric (a `runs.csv` column).
    pub metric: String,
    /// Seeds with a finite value.
    pub n: usize,
    /// Mean over the seeds.
    pub mean: f64,
    /// Lower end of the 95% interval of the mean.
    pub ci95_low: f64,
    /// Upper end.
    pub ci95_high: f64,
}

/// The finite values of metric `index` in `rows`, by seed.
fn values_by_seed<'a>(rows: impl Iterator<Item = &'a RunRow>, index: usize) -> Vec<(u64, f64)> {
    rows.map(|r| (r.seed, r.values[index]))
        .filter(|(_, v)| v.is_finite())
        .collect()
}

/// Per cell (in `cells` order), method and summarised metric: the mean and
/// the 95% interval over the rows' seeds. The interval is Student t's, cut
/// to the values the metric can take (a rate's stays in [0, 1], ANEES's
/// above 0): the mean lies there, so the cut loses no coverage.
pub fn summarise(rows: &[RunRow], cells: &[String], methods: &[RunMethod]) -> Vec<SummaryRow> {
    let mut out = Vec::new();
    for (cell, method) in cells
        .iter()
        .flat_map(|c| methods.iter().map(move |m| (c, m)))
    {
        let mine = || {
            rows.iter()
                .filter(|r| &r.cell == cell && r.method == method.as_str())
        };
        for (index, metric) in METRICS.iter().enumerate() {
            if !metric.summarised() {
                continue;
            }
            let values: Vec<f64> = values_by_seed(mine(), index)
                .into_iter()
                .map(|(_, v)| v)
                .collect();
            let (mean, half) = mean_and_half_width(&values);
            let (low, high) = metric.range;
            // NaN (no interval) stays NaN.
            let cut = |v: f64| if v.is_nan() { v } else { v.clamp(low, high) };
            out.push(SummaryRow {
                cell: cell.clone(),
                method: method.as_str().into(),
                metric: metric.name.into(),
                n: values.len(),
                mean,
                ci95_low: cut(mean - half),
                ci95_high: cut(mean + half),
            });
        }
    }
    out
}

/// What report.html says of a pair with fewer than two seeds (its verdict
/// `within_noise`): there is no interval. (`sigmap run`'s summary prints no
/// paired table for a one-seed run.)
pub const NO_INTERVAL: &str = "one seed: no interval";

/// What a paired difference says of a method against the reference.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The whole 95% interval lies on the metric's better side.
    Better,
    /// The whole interval lies on its worse side.
    Worse,
    /// The interval holds no difference, or there are fewer than two
    /// paired seeds.
    WithinNoise,
}

impl Verdict {
    /// Its name in `paired.csv`.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Better => "better",
            Verdict::Worse => "worse",
            Verdict::WithinNoise => "within_noise",
        }
    }

    /// The verdict of a 95% interval `[low, high]` of per-seed differences in
    /// which lower is better.
    fn of_lower_is_better((low, high): (f64, f64)) -> Self {
        if high < 0.0 {
            Verdict::Better
        } else if low > 0.0 {
            Verdict::Worse
        } else {
            Verdict::WithinNoise
        }
    }
}

/// One row of `paired.csv`: a method against the reference on one metric of
/// one sweep cell, over the seeds where both have a finite value. The
/// reference is another method in the same cell, or (a `[[sweep]]` axis with
/// a `reference` value) the same method in the cell that differs only on
/// that axis.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PairedRow {
    /// The sweep cell.
    pub cell: String,
    /// The method.
    pub method: String,
    /// The method it is compared with.
    pub reference: String,
    /// The cell of the reference: `cell` itself when two methods are
    /// compared, the cell at the axis's reference value otherwise.
    pub reference_cell: String,
    /// The metric (a `runs.csv` column).
    pub metric: String,
    /// Seeds paired.
    pub n: usize,
    /// Mean of the per-seed differences, method − reference.
    pub mean: f64,
    /// Lower end of their 95% Student t interval.
    pub ci95_low: f64,
    /// Upper end.
    pub ci95_high: f64,
    /// Better, worse or within the noise, by the metric's direction.
    pub verdict: Verdict,
}

/// The paired comparison of a method with the reference on one metric.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairedDifference {
    /// Seeds where both are finite.
    pub n: usize,
    /// Mean of the per-seed differences, method − reference.
    pub mean: f64,
    /// Its 95% Student t interval (NaN for one seed).
    pub ci95: (f64, f64),
    /// What the interval says, by the metric's direction.
    pub verdict: Verdict,
}

impl PairedDifference {
    /// The per-seed differences `method − reference` over the seeds where
    /// both are finite (values as `(seed, value)`), their mean, 95% interval
    /// and verdict. For a metric with a target value (ANEES, coverage) the
    /// verdict ranks the per-seed change of the distance to the target,
    /// `|m − t| − |r − t|`, by its own interval. `None` when no seed pairs.
    pub fn of(method: &[(u64, f64)], reference: &[(u64, f64)], better: Better) -> Option<Self> {
        let by_seed: std::collections::BTreeMap<u64, f64> = reference.iter().copied().collect();
        let pairs: Vec<(f64, f64)> = method
            .iter()
            .filter_map(|(seed, m)| Some((*m, *by_seed.get(seed)?)))
            .filter(|(m, r)| m.is_finite() && r.is_finite())
            .collect();
        if pairs.is_empty() {
            return None;
        }
        let interval = |values: Vec<f64>| {
            let (mean, half) = mean_and_half_width(&values);
            (mean, (mean - half, mean + half))
        };
        let (mean, ci95) = interval(pairs.iter().map(|(m, r)| m - r).collect());
        let verdict = match better {
            _ if pairs.len() < 2 => Verdict::WithinNoise,
            Better::Lower => Verdict::of_lower_is_better(ci95),
            Better::Higher => Verdict::of_lower_is_better((-ci95.1, -ci95.0)),
            Better::Toward(target) => {
                let distance = |(m, r): &(f64, f64)| (m - target).abs() - (r - target).abs();
                Verdict::of_lower_is_better(interval(pairs.iter().map(distance).collect()).1)
            }
            Better::Unranked => Verdict::WithinNoise,
        };
        Some(Self {
            n: pairs.len(),
            mean,
            ci95,
            verdict,
        })
    }
}

/// Per cell (in `cells` order), every method but `reference` (in `methods`
/// order) and every summarised metric: the paired comparison with
/// `reference`. A metric no seed pairs on (ANEES of the ray update) has no
/// row.
pub fn paired(
    rows: &[RunRow],
    cells: &[String],
    methods: &[RunMethod],
    reference: &RunMethod,
) -> Vec<PairedRow> {
    let mut out = Vec::new();
    for cell in cells {
        let of = |method: &RunMethod, index: usize| -> Vec<(u64, f64)> {
            let mine = rows
                .iter()
                .filter(|r| &r.cell == cell && r.method == method.as_str());
            values_by_seed(mine, index)
        };
        for method in methods.iter().filter(|&m| m != reference) {
            for (index, metric) in METRICS.iter().enumerate() {
                if !metric.summarised() {
                    continue;
                }
                let difference =
                    PairedDifference::of(&of(method, index), &of(reference, index), metric.better);
                if let Some(difference) = difference {
                    out.push(paired_row(
                        (cell, cell),
                        (method, reference),
                        metric,
                        difference,
                    ));
                }
            }
        }
    }
    out
}

/// For every sweep axis with a `reference` value, every cell off that value
/// and every method: the method against itself in the cell that differs only
/// on that axis, metric by metric (rows in axis, cell, method order). A
/// metric no seed pairs on has no row.
pub fn paired_across_axes(
    rows: &[RunRow],
    axes: &[SweepAxis],
    cells: &[Vec<(String, SweepValue)>],
    methods: &[RunMethod],
) -> Vec<PairedRow> {
    let mut out = Vec::new();
    let of = |cell: &str, method: &RunMethod, index: usize| -> Vec<(u64, f64)> {
        let mine = rows
            .iter()
            .filter(|r| r.cell == cell && r.method == method.as_str());
        values_by_seed(mine, index)
    };
    for axis in axes {
        let Some(reference_value) = &axis.reference else {
            continue;
        };
        for cell in cells {
            let Some(at) = cell.iter().position(|(field, _)| field == &axis.field) else {
                continue;
            };
            if &cell[at].1 == reference_value {
                continue;
            }
            let mut reference_cell = cell.clone();
            reference_cell[at].1 = reference_value.clone();
            let (label, reference_label) = (
                Experiment::cell_label(cell),
                Experiment::cell_label(&reference_cell),
            );
            for method in methods {
                for (index, metric) in METRICS.iter().enumerate() {
                    if !metric.summarised() {
                        continue;
                    }
                    let difference = PairedDifference::of(
                        &of(&label, method, index),
                        &of(&reference_label, method, index),
                        metric.better,
                    );
                    if let Some(difference) = difference {
                        out.push(paired_row(
                            (&label, &reference_label),
                            (method, method),
                            metric,
                            difference,
                        ));
                    }
                }
            }
        }
    }
    out
}

impl PairedRow {
    /// Whether it compares two methods of one cell (not one method across
    /// an axis).
    pub fn is_between_methods(&self) -> bool {
        self.reference_cell == self.cell
    }
}

fn paired_row(
    (cell, reference_cell): (&str, &str),
    (method, reference): (&RunMethod, &RunMethod),
    metric: &Metric,
    difference: PairedDifference,
) -> PairedRow {
    PairedRow {
        cell: cell.into(),
        method: method.as_str().into(),
        reference: reference.as_str().into(),
        reference_cell: reference_cell.into(),
        metric: metric.name.into(),
        n: difference.n,
        mean: difference.mean,
        ci95_low: difference.ci95.0,
        ci95_high: difference.ci95.1,
        verdict: difference.verdict,
    }
}

#[cfg(test)]
mod tests;
