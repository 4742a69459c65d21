//! `sigmap regress`: exit 1 with a table of what drifted from the baseline.

use super::RegressArgs;
use crate::error::{Error, Result};
use crate::experiment::study::regress::{compare, read_summary};

/// `sigmap regress`.
pub(crate) fn run(args: RegressArgs) -> Result<()> {
    let current = read_summary(&args.current)?;
    let baseline = read_summary(&args.baseline)?;
    if !baseline.iter().any(|b| b.mean.is_finite()) {
        return Err(Error::input(
            &args.baseline,
            "has no finite metric: nothing to compare against",
        ));
    }
    let mut overrides = Vec::new();
    for t in &args.tolerance {
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
    let results = compare(&current, &baseline, &overrides);
    let regressed: Vec<_> = results.iter().filter(|c| c.regressed()).collect();
    // A metric the baseline holds as NaN (the ray update's ANEES) has
    // nothing to compare against, in either message.
    let compared = results.iter().filter(|c| !c.baseline.is_nan()).count();
    if regressed.is_empty() {
        println!(
            "no regression: {compared} metrics within tolerance of {}",
            args.baseline.display()
        );
        return Ok(());
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
    Err(Error::CheckFailed(format!(
        "{} of {compared} metrics regressed against {}",
        regressed.len(),
        args.baseline.display()
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
