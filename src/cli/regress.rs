//! `sigmap regress`: exit 1 with a table of what drifted from the baseline.

use super::RegressArgs;
use crate::error::{Error, Result};
use crate::experiment::study::regress::{
    check_consistency, compare, read_summary, ConsistencyCheck,
};
use crate::experiment::study::summary::SummaryRow;
use std::path::Path;

/// `sigmap regress`: the baseline's comparison, then the consistency
/// checks; fails (exit 1) if either does.
pub(crate) fn run(args: RegressArgs) -> Result<()> {
    if args.baseline.is_none() {
        if args.consistent.is_empty() {
            return Err(Error::Usage(
                "regress: nothing to check: give --baseline BASELINE.csv, --consistent METHOD, \
                 or both"
                    .into(),
            ));
        }
        if !args.tolerance.is_empty() {
            return Err(Error::Usage(
                "--tolerance needs --baseline: it is the drift allowed from the baseline".into(),
            ));
        }
    }
    let current = read_summary(&args.current)?;
    // Every check is read before any is judged: a bad input is exit 2.
    let checks = args
        .consistent
        .iter()
        .map(|method| Ok((method.as_str(), check_consistency(&current, method)?)))
        .collect::<std::result::Result<Vec<_>, String>>()
        .map_err(|e| Error::input(&args.current, e))?;
    let regressed = match &args.baseline {
        Some(baseline) => against_baseline(&current, baseline, &args.tolerance)?,
        None => None,
    };
    let inconsistent = consistency(&checks);
    match (regressed, inconsistent) {
        (None, None) => Ok(()),
        (Some(a), Some(b)) => Err(Error::CheckFailed(format!("{a}; {b}"))),
        (Some(failure), None) | (None, Some(failure)) => Err(Error::CheckFailed(failure)),
    }
}

/// Prints each method's consistency check, cell by cell; what failed, if
/// anything.
fn consistency(checks: &[(&str, Vec<ConsistencyCheck>)]) -> Option<String> {
    let mut failed = 0;
    for (method, cells) in checks {
        for check in cells {
            failed += usize::from(check.failed());
            println!(
                "{} {method}{}: mean NEES of one point a run {} over {} seeds, band [{:.2}, {:.2}]",
                check.verdict.map_or("no value:", |v| v.as_str()),
                if check.cell.is_empty() {
                    String::new()
                } else {
                    format!(" (cell {})", check.cell)
                },
                column(check.mean, false),
                check.n,
                check.band.0,
                check.band.1,
            );
        }
    }
    let judged: usize = checks.iter().map(|(_, cells)| cells.len()).sum();
    (failed > 0).then(|| format!("{failed} of {judged} consistency checks failed"))
}

/// Compares `current` with the baseline at `path`, printing what
/// regressed; what failed, if anything.
fn against_baseline(
    current: &[SummaryRow],
    path: &Path,
    tolerances: &[String],
) -> Result<Option<String>> {
    let baseline = read_summary(path)?;
    if !baseline.iter().any(|b| b.mean.is_finite()) {
        return Err(Error::input(
            path,
            "has no finite metric: nothing to compare against",
        ));
    }
    let mut overrides = Vec::new();
    for t in tolerances {
        let (metric, value) = t
            .split_once('=')
            .and_then(|(m, v)| Some((m.to_string(), v.parse::<f64>().ok().filter(|v| *v >= 0.0)?)))
            .ok_or_else(|| {
                Error::Usage(format!(
                    "--tolerance '{t}': expected METRIC=VALUE with VALUE >= 0"
                ))
            })?;
        if !baseline.iter().any(|b| b.metric == metric) {
            return Err(Error::Usage(format!(
                "--tolerance '{t}': the baseline has no metric '{metric}'"
            )));
        }
        overrides.push((metric, value));
    }
    let results = compare(current, &baseline, &overrides);
    let regressed: Vec<_> = results.iter().filter(|c| c.regressed()).collect();
    // A metric the baseline holds as NaN (the ray update's ANEES) has
    // nothing to compare against, in either message.
    let compared = results.iter().filter(|c| !c.baseline.is_nan()).count();
    if regressed.is_empty() {
        println!(
            "no regression: {compared} metrics within tolerance of {}",
            path.display()
        );
        return Ok(None);
    }
    println!(
        "{:<11} {:<23} {:>12} {:>12} {:>10} {:>10}",
        "method", "metric", "baseline", "current", "change", "tolerance"
    );
    for c in &regressed {
        println!(
            "{:<11} {:<23} {:>12} {:>12} {:>10} {:>10}",
            c.method,
            c.metric,
            column(c.baseline, false),
            column(c.current, false),
            column(c.current - c.baseline, true),
            column(c.tolerance, false)
        );
    }
    Ok(Some(format!(
        "{} of {compared} metrics regressed against {}",
        regressed.len(),
        path.display()
    )))
}

/// A number of the table: five decimals, or in scientific notation where
/// that would not fit its column; `signed` puts a sign on it.
fn column(value: f64, signed: bool) -> String {
    let fits = value.is_finite() && value.abs() < 1e6 && (value == 0.0 || value.abs() >= 1e-5);
    match (fits, signed) {
        (true, true) => format!("{value:+.5}"),
        (true, false) => format!("{value:.5}"),
        (false, true) => format!("{value:+.4e}"),
        (false, false) => format!("{value:.4e}"),
    }
}
