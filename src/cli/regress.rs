//! `sigmap regress`: exit 1 with a table of what drifted from the baseline.

use super::RegressArgs;
use crate::error::{Error, Result};
use crate::experiment::regress::compare;
use crate::experiment::runner::{read_rows, SummaryRow};

/// `sigmap regress`.
pub(crate) fn run(args: RegressArgs) -> Result<()> {
    for path in [&args.current, &args.baseline] {
        if !path.exists() {
            return Err(Error::input(path, "file not found"));
        }
    }
    let current: Vec<SummaryRow> = read_rows(&args.current)?;
    let baseline: Vec<SummaryRow> = read_rows(&args.baseline)?;
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
        overrides.push((metric, value));
    }
    let results = compare(&current, &baseline, &overrides);
    let regressed: Vec<_> = results.iter().filter(|c| c.regressed()).collect();
    if regressed.is_empty() {
        println!(
            "no regression: {} metrics within tolerance of {}",
            results.len(),
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
            "{:<11} {:<23} {:>12.5} {:>12.5} {:>+10.5} {:>10.5}",
            c.method,
            c.metric,
            c.baseline,
            c.current,
            c.current - c.baseline,
            c.tolerance
        );
    }
    Err(Error::CheckFailed(format!(
        "{} of {} metrics regressed against {}",
        regressed.len(),
        results.len(),
        args.baseline.display()
    )))
}
