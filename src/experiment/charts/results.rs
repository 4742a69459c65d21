//! The charts of `sigmap run`: each score against the sweep axis per method
//! with 95% intervals, and the coverage of the propagated covariances (the
//! slice of each map against the truth: [`super::slice`]).

use crate::error::Result;
use crate::experiment::charts::{panel_grid, panels, Panel, Series, IN_PLOT_LEGEND};
use crate::experiment::study::summary::SummaryRow;
use crate::experiment::RunMethod;
use crate::experiment::{Experiment, SweepValue};
use crate::uncertainty::consistency::expected_coverage;
use std::path::{Path, PathBuf};

fn mean<'a>(
    summary: &'a [SummaryRow],
    cell: &str,
    method: &RunMethod,
    metric: &str,
) -> Option<&'a SummaryRow> {
    summary
        .iter()
        .find(|s| s.cell == cell && s.method == method.as_str() && s.metric == metric)
}

/// The first sweep axis as a chart's x axis: its label, and where each
/// value lies (a string axis, profiles or scenes, at its value's index).
struct FirstAxis {
    label: String,
    texts: Vec<String>,
}

impl FirstAxis {
    /// The first axis of `cells`; `None` without a sweep.
    fn of(cells: &[Vec<(String, SweepValue)>]) -> Option<Self> {
        let field = cells.first()?.first()?.0.clone();
        let texts: Vec<String> = cells
            .iter()
            .filter_map(|c| match &c[0].1 {
                SweepValue::Text(t) => Some(t.clone()),
                SweepValue::Number(_) => None,
            })
            .fold(Vec::new(), |mut seen, t| {
                if !seen.contains(&t) {
                    seen.push(t);
                }
                seen
            });
        let label = if texts.is_empty() {
            field
        } else {
            format!("{field} (index: {})", texts.join(", "))
        };
        Some(Self { label, texts })
    }

    /// Where `value` lies on the axis.
    fn x(&self, value: &SweepValue) -> f64 {
        match value {
            SweepValue::Number(x) => *x,
            SweepValue::Text(t) => self.texts.iter().position(|s| s == t).unwrap_or(0) as f64,
        }
    }
}

/// One chart line: a method's means over the first sweep axis at one value
/// of the other axes (`rest`, empty without them).
struct Line {
    method: String,
    rest: String,
    points: Vec<(f64, f64)>,
    intervals: Vec<(f64, f64, f64)>,
}

/// The line of `method` at `rest`, appended empty if there is none yet.
fn line_of<'a>(lines: &'a mut Vec<Line>, method: &RunMethod, rest: String) -> &'a mut Line {
    let method = method.to_string();
    let index = match lines
        .iter()
        .position(|l| l.method == method && l.rest == rest)
    {
        Some(i) => i,
        None => {
            lines.push(Line {
                method,
                rest,
                points: Vec::new(),
                intervals: Vec::new(),
            });
            lines.len() - 1
        }
    };
    &mut lines[index]
}

/// A cell's values as a chart names them: `field=value` joined by `; `, the
/// experiment file's fields without their `experiment.` prefix.
fn legend_label(cell: &[(String, SweepValue)]) -> String {
    cell.iter()
        .map(|(field, value)| {
            let field = field.strip_prefix("experiment.").unwrap_or(field);
            format!("{field}={value}")
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// A panel's lines, and its method when the figure has a panel per method.
type MethodPanel = (Option<String>, Vec<Series>);

/// The panels of a figure of `lines`: one panel naming each line `method
/// rest`; or, when that panel would hold more than [`IN_PLOT_LEGEND`] lines
/// of several methods at several values of the other axes, one panel per
/// method (its name returned beside it) whose lines are named by those
/// values alone, so that a value keeps its colour from panel to panel.
fn by_method(lines: Vec<Line>) -> Vec<MethodPanel> {
    let distinct = |of: &dyn Fn(&Line) -> &str| {
        lines.iter().fold(Vec::<String>::new(), |mut seen, l| {
            if !seen.iter().any(|s| s == of(l)) {
                seen.push(of(l).to_string());
            }
            seen
        })
    };
    let methods = distinct(&|l| &l.method);
    let rests = distinct(&|l| &l.rest);
    let series = |l: Line, name: String| Series {
        name,
        points: l.points,
        intervals: l.intervals,
    };
    if lines.len() <= IN_PLOT_LEGEND || methods.len() < 2 || rests.len() < 2 {
        let all = lines
            .into_iter()
            .map(|l| {
                let name = if l.rest.is_empty() {
                    l.method.clone()
                } else {
                    format!("{} {}", l.method, l.rest)
                };
                series(l, name)
            })
            .collect();
        return vec![(None, all)];
    }
    let mut panels: Vec<MethodPanel> = methods
        .iter()
        .map(|m| (Some(m.clone()), Vec::new()))
        .collect();
    for line in lines {
        let at = methods.iter().position(|m| *m == line.method).unwrap_or(0);
        let name = line.rest.clone();
        panels[at].1.push(series(line, name));
    }
    panels
}

/// One line per method (and value of the other axes) of `metric`'s means
/// against the first axis, with their 95% intervals.
fn lines_over_cells(
    summary: &[SummaryRow],
    cells: &[Vec<(String, SweepValue)>],
    methods: &[RunMethod],
    axis: &FirstAxis,
    metric: &str,
) -> Vec<Line> {
    let label = |cell: &[(String, SweepValue)]| Experiment::cell_label(cell);
    let mut out: Vec<Line> = Vec::new();
    for method in methods {
        for cell in cells {
            let Some(row) = mean(summary, &label(cell), method, metric) else {
                continue;
            };
            if !row.mean.is_finite() {
                continue;
            }
            let x = axis.x(&cell[0].1);
            let line = line_of(&mut out, method, legend_label(&cell[1..]));
            line.points.push((x, row.mean));
            if row.ci95_low.is_finite() {
                line.intervals.push((x, row.ci95_low, row.ci95_high));
            }
        }
    }
    out
}

/// The panels' titles of a row of [`by_method`]: `title`, and the method
/// when the row has a panel per method.
fn titles(title: &str, row: &[MethodPanel]) -> Vec<String> {
    row.iter()
        .map(|(method, _)| match method {
            Some(method) => format!("{title}: {method}"),
            None => title.to_string(),
        })
        .collect()
}

/// The panels of a row of [`by_method`] with their `titles`.
fn row_panels<'a>(
    row: &'a [MethodPanel],
    titles: &'a [String],
    (x_label, y_label): (&'a str, &'a str),
    log_y: bool,
) -> impl Iterator<Item = Panel<'a>> {
    row.iter()
        .zip(titles)
        .map(move |((_, series), title)| Panel {
            title,
            x_label,
            y_label,
            log_x: false,
            log_y,
            series,
        })
}

/// `scores.svg`: F1, false-free rate, Brier and ANEES against the first sweep
/// axis, one line per method (and value of the other axes), 95% intervals;
/// and `score_<metric>.svg` beside it for every metric of `summary.csv`.
pub fn plot_scores(
    path: &Path,
    summary: &[SummaryRow],
    cells: &[Vec<(String, SweepValue)>],
    methods: &[RunMethod],
) -> Result<Vec<PathBuf>> {
    let Some(axis) = FirstAxis::of(cells) else {
        return Ok(Vec::new());
    };
    let panels_for =
        |metric: &str| by_method(lines_over_cells(summary, cells, methods, &axis, metric));
    let metrics = [
        ("f1", "occupied F1", false),
        ("false_free_rate", "false-free rate", false),
        ("brier", "Brier score", false),
        ("anees", "ANEES (3 = honest)", true),
    ];
    // One row per metric: a panel, or one per method when crowded.
    let rows: Vec<(Vec<MethodPanel>, &str, bool)> = metrics
        .iter()
        .map(|(m, title, log)| (panels_for(m), *title, *log))
        .collect();
    let names: Vec<Vec<String>> = rows
        .iter()
        .map(|(row, title, _)| titles(title, row))
        .collect();
    let list: Vec<Panel> = rows
        .iter()
        .zip(&names)
        .flat_map(|((row, title, log), names)| row_panels(row, names, (&axis.label, title), *log))
        .collect();
    let columns = rows.iter().map(|(row, _, _)| row.len()).max().unwrap_or(1);
    if columns > 1 {
        panel_grid(path, columns, &list)?;
    } else {
        panels(path, &list)?;
    }
    let mut written = vec![path.to_path_buf()];
    // And every metric of summary.csv on its own chart, beside the overview.
    let dir = path.parent().unwrap_or(Path::new("."));
    for metric in crate::experiment::study::metrics::summarised().map(|m| m.name) {
        let row = panels_for(metric);
        let names = titles(metric, &row);
        let list: Vec<Panel> =
            row_panels(&row, &names, (&axis.label, metric), metric == "anees").collect();
        let chart = dir.join(format!("score_{metric}.svg"));
        panels(&chart, &list)?;
        written.push(chart);
    }
    Ok(written)
}

/// `safety.svg`, when the experiment sweeps the risk level
/// (`experiment.risk`): the safety curve, false-free rate against precision
/// as ε varies, one line per method (and value of the other axes), 95%
/// intervals of the false-free rate. A method that ignores ε (the ray
/// update) is a single point.
pub fn plot_safety(
    path: &Path,
    summary: &[SummaryRow],
    cells: &[Vec<(String, SweepValue)>],
    methods: &[RunMethod],
) -> Result<Vec<PathBuf>> {
    let Some(risk_axis) = cells
        .first()
        .and_then(|c| c.iter().position(|(f, _)| f == "experiment.risk"))
    else {
        return Ok(Vec::new());
    };
    let mut lines: Vec<Line> = Vec::new();
    for method in methods {
        for cell in cells {
            let others: Vec<(String, SweepValue)> = cell
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != risk_axis)
                .map(|(_, v)| v.clone())
                .collect();
            let label = Experiment::cell_label(cell);
            let (Some(precision), Some(false_free)) = (
                mean(summary, &label, method, "precision"),
                mean(summary, &label, method, "false_free_rate"),
            ) else {
                continue;
            };
            if !(precision.mean.is_finite() && false_free.mean.is_finite()) {
                continue;
            }
            let line = line_of(&mut lines, method, legend_label(&others));
            let x = precision.mean;
            line.points.push((x, false_free.mean));
            if false_free.ci95_low.is_finite() {
                line.intervals
                    .push((x, false_free.ci95_low, false_free.ci95_high));
            }
        }
    }
    let title = "safety curve: false-free rate vs precision as the risk level varies";
    let row = by_method(lines);
    let names = titles(title, &row);
    let labels = ("precision", "false-free rate (lower is safer)");
    let list: Vec<Panel> = row_panels(&row, &names, labels, false).collect();
    panels(path, &list)?;
    Ok(vec![path.to_path_buf()])
}

/// `coverage.svg`: the share of true points inside the 1, 2, 3 sigma
/// ellipsoids per method (first cell) against the χ²₃ expectation.
pub fn plot_coverage(
    path: &Path,
    summary: &[SummaryRow],
    cell: &str,
    methods: &[RunMethod],
) -> Result<()> {
    let mut series: Vec<Series> = methods
        .iter()
        .filter_map(|m| {
            let points: Vec<(f64, f64)> = ["coverage_1sigma", "coverage_2sigma", "coverage_3sigma"]
                .iter()
                .enumerate()
                .filter_map(|(k, metric)| {
                    mean(summary, cell, m, metric).map(|r| ((k + 1) as f64, r.mean))
                })
                .filter(|(_, v)| v.is_finite())
                .collect();
            (!points.is_empty()).then(|| Series {
                name: m.to_string(),
                points,
                intervals: Vec::new(),
            })
        })
        .collect();
    series.push(Series {
        name: "expected (χ², 3 DOF)".into(),
        points: (1..=3)
            .map(|k| (k as f64, expected_coverage(k as f64, 3)))
            .collect(),
        intervals: Vec::new(),
    });
    panels(
        path,
        &[Panel {
            title: "coverage of the propagated covariances",
            x_label: "k (sigma)",
            y_label: "share of true points inside the k-sigma ellipsoid",
            log_x: false,
            log_y: false,
            series: &series,
        }],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(methods: &[&str], rests: usize) -> Vec<Line> {
        methods
            .iter()
            .flat_map(|m| {
                (0..rests).map(move |r| Line {
                    method: m.to_string(),
                    rest: format!("risk={r}"),
                    points: vec![(0.0, r as f64)],
                    intervals: Vec::new(),
                })
            })
            .collect()
    }

    #[test]
    fn a_crowded_figure_gets_a_panel_per_method_whose_lines_are_the_other_values() {
        let panels = by_method(lines(&["unscented", "ray_update", "registered_truth"], 4));
        assert_eq!(panels.len(), 3);
        for ((method, series), want) in
            panels
                .iter()
                .zip(["unscented", "ray_update", "registered_truth"])
        {
            assert_eq!(method.as_deref(), Some(want));
            let names: Vec<&str> = series.iter().map(|s| s.name.as_str()).collect();
            assert_eq!(names, ["risk=0", "risk=1", "risk=2", "risk=3"]);
        }
        // Few enough lines for one panel: each named by method and values.
        let one = by_method(lines(&["unscented", "ray_update"], 3));
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].0, None);
        assert_eq!(one[0].1.len(), 6);
        assert_eq!(one[0].1[4].name, "ray_update risk=1");
        // One method, however many lines: one panel.
        assert_eq!(by_method(lines(&["unscented"], 12)).len(), 1);
    }

    #[test]
    fn legends_name_the_experiment_files_fields_without_their_prefix() {
        let cell = vec![
            ("experiment.risk".to_string(), SweepValue::Number(0.5)),
            (
                "profile.range.sigma0".to_string(),
                SweepValue::Number(0.001),
            ),
        ];
        assert_eq!(legend_label(&cell), "risk=0.5; profile.range.sigma0=0.001");
    }
}
