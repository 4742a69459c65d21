//! `report.html`: one self-contained page beside a run's files — the
//! experiment, sigmap's version and the input fingerprint, the headline
//! scores with their 95% intervals per sweep cell, and every chart inline
//! (SVG in the page; nothing is fetched). Written by `sigmap run` and
//! `sigmap merge`; like the other outputs, the same inputs give the same
//! bytes (no dates, no timings).

use crate::error::{Error, Result};
use crate::experiment::study::batch::Study;
use crate::experiment::study::journal::Inputs;
use crate::experiment::study::summary::{PairedRow, SummaryRow, Verdict};
use crate::experiment::Experiment;
use crate::files::write_file;
use crate::uncertainty::consistency::Consistency;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The metrics of the headline tables (the report's and the terminal's):
/// (column, title, digits).
pub const HEADLINE: [(&str, &str, usize); 8] = [
    ("precision", "precision", 3),
    ("recall", "recall", 3),
    ("f1", "F1", 3),
    ("false_free_rate", "false-free", 4),
    ("unknown_fraction", "unknown", 3),
    ("brier", "Brier", 3),
    ("roc_auc", "ROC AUC", 3),
    ("anees", "ANEES", 2),
];

/// What each chart shows, by file name (`score_<metric>.svg` are captioned
/// by their metric).
fn caption(name: &str) -> String {
    match name {
        "scores.svg" => {
            "F1, false-free rate, Brier and ANEES against the sweep, one line per method \
             and value of the other axes, a panel per method when those are more than six \
             (bars: 95% intervals over the seeds)"
                .into()
        }
        "safety.svg" => "The safety curve: false-free rate against precision as the risk level varies".into(),
        "coverage.svg" => {
            "Coverage: the share of true points inside the 1, 2, 3 sigma ellipsoids, against the χ² expectation"
                .into()
        }
        "slice.svg" => {
            "A horizontal slice through the objects, first seed: each map against the truth \
             (correct occupied, correct free, false-free, false-occupied, unknown)"
                .into()
        }
        other => match other.strip_prefix("score_").and_then(|n| n.strip_suffix(".svg")) {
            Some(metric) => format!("{metric} against the sweep"),
            None => other.into(),
        },
    }
}

/// The map settings in words, the uncertainty-aware maps' and the ray
/// update's, as the file sets them; a sweep over one of them is named, as it
/// varies it cell by cell.
fn map_settings(experiment: &Experiment) -> (String, String) {
    let (mut opdf, mut rays) = experiment.map().describe();
    let swept: Vec<String> = experiment.cells().first().map_or_else(Vec::new, |cell| {
        cell.iter()
            .map(|(field, _)| field.clone())
            .filter(|f| {
                ["risk", "beam_pooling", "interpolate_beams", "sample_gate"]
                    .iter()
                    .any(|name| f.strip_prefix("experiment.") == Some(name))
            })
            .collect()
    });
    if !swept.is_empty() {
        let _ = write!(
            opdf,
            " (as the file sets them; swept: {})",
            swept.join(", ")
        );
    }
    if swept.iter().any(|f| f == "experiment.beam_pooling") {
        rays.push_str(" (as the file sets it; swept: experiment.beam_pooling)");
    }
    (opdf, rays)
}

/// Text made safe for HTML.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1440px;margin:2em auto;padding:0 1em;color:#222}\
h1{margin-bottom:0.2em}table{border-collapse:collapse;margin:0.5em 0 1.5em}\
th,td{border:1px solid #ccc;padding:0.25em 0.6em;text-align:right}\
th:first-child,td:first-child{text-align:left}th{background:#f2f2f2}\
td small{color:#666}figure{margin:1em 0 2em}figure svg{max-width:100%;height:auto}\
figcaption{color:#444;margin-top:0.3em}dl{display:grid;grid-template-columns:max-content auto;gap:0.2em 1em}\
dt{font-weight:bold}dd{margin:0;font-family:monospace}.description{white-space:pre-wrap}\
td.better{background:#e3f4e1}td.worse{background:#fbe2e0}td.within_noise{color:#555}";

/// The page for a finished run folder: `charts` are the SVG files to
/// show, in order (missing ones are skipped).
pub fn render(
    experiment: &Experiment,
    study: &Study,
    inputs: &Inputs,
    charts: &[PathBuf],
) -> Result<String> {
    let mut html = String::new();
    let name = escape(experiment.name());
    let _ = write!(
        html,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>sigmap: {name}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n\
         <h1>{name}</h1>\n<p class=\"description\">{}</p>\n<dl>\n",
        escape(experiment.description())
    );
    let seeds: Vec<String> = experiment.seeds().iter().map(u64::to_string).collect();
    let (opdf, rays) = map_settings(experiment);
    let methods: Vec<&str> = experiment
        .methods()
        .iter()
        .map(crate::experiment::study::run_method::RunMethod::as_str)
        .collect();
    for (term, value) in [
        ("sigmap", env!("CARGO_PKG_VERSION").to_string()),
        ("input fingerprint", inputs.fingerprint.clone()),
        ("seeds", seeds.join(", ")),
        ("methods", methods.join(", ")),
        ("resolution", format!("{} m", experiment.resolution())),
        ("sweep cells", experiment.cells().len().to_string()),
        ("uncertainty-aware maps", opdf),
        ("ray update", rays),
        ("errors the maps are told", super::told_errors(experiment)),
    ] {
        let _ = writeln!(html, "<dt>{term}</dt><dd>{}</dd>", escape(&value));
    }
    html.push_str("</dl>\n<details><summary>Input files and their hashes</summary>\n<table>\n");
    html.push_str("<tr><th>file</th><th>hash</th></tr>\n");
    for (file, hash) in &inputs.files {
        let _ = writeln!(
            html,
            "<tr><td>{}</td><td>{}</td></tr>",
            escape(file),
            escape(hash)
        );
    }
    html.push_str("</table>\n</details>\n");
    headline(&mut html, experiment, &study.summary, &study.paired);
    consistency(&mut html, &study.summary);
    html.push_str("<h2>Charts</h2>\n");
    let mut per_metric = String::new();
    for chart in charts {
        let Ok(svg) = std::fs::read_to_string(chart) else {
            continue;
        };
        let file = chart
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let start = svg
            .find("<svg")
            .ok_or_else(|| Error::input(chart, "not an SVG chart"))?;
        let figure = format!(
            "<figure id=\"{}\">\n{}\n<figcaption>{} (<code>{}</code>)</figcaption>\n</figure>\n",
            escape(file.trim_end_matches(".svg")),
            &svg[start..],
            escape(&caption(&file)),
            escape(&file)
        );
        if file.starts_with("score_") {
            per_metric.push_str(&figure);
        } else {
            html.push_str(&figure);
        }
    }
    if !per_metric.is_empty() {
        html.push_str(
            "<details><summary>Every metric of summary.csv against the sweep</summary>\n",
        );
        html.push_str(&per_metric);
        html.push_str("</details>\n");
    }
    html.push_str(
        "<p><small>Written by <code>sigmap run</code> / <code>sigmap merge</code>; the numbers are \
         those of summary.csv (mean over the seeds, 95% interval of the mean, cut to the \
         metric's range) and paired.csv (mean per-seed difference against the reference, its \
         95% Student t interval and verdict).</small></p>\n\
         </body>\n</html>\n",
    );
    Ok(html)
}

/// One table per sweep cell: a row per method, each headline metric as
/// `mean` over `[low, high]`; beside it the paired table, a row per method
/// but the reference, each metric's mean per-seed difference, interval and
/// verdict.
fn headline(
    html: &mut String,
    experiment: &Experiment,
    summary: &[SummaryRow],
    paired: &[PairedRow],
) {
    html.push_str("<h2>Scores</h2>\n");
    let _ = writeln!(
        html,
        "<p>Means over {}, with the 95% interval of the mean; the full table is \
         summary.csv, every run runs.csv. Two methods of a seed map the same scans, so \
         they are compared seed by seed: the second table gives each method's mean \
         difference from <b>{}</b> (method − {}), its 95% interval and the verdict \
         (paired.csv). Higher is better for precision, recall, F1 and ROC AUC; lower for \
         false-free (truly occupied cells the map calls free: the collision risk), unknown \
         and Brier; an ANEES of 3 means honest covariances; – : the method propagates \
         none.</p>",
        super::count(experiment.seeds().len(), "seed"),
        experiment.reference(),
        experiment.reference()
    );
    if let Some(risk) = experiment.map().model.risk {
        let _ = writeln!(
            html,
            "<p>The uncertainty-aware maps use the risk level ε = {risk} (docs/math.md §5.4, \
             §5.7): a cell is called free only when it is free with probability at least \
             1 − ε, and is left unknown otherwise. What that costs is the <b>unknown</b> \
             column: the share of the observable cells each map leaves unknown (the ray \
             update's, which ignores ε, beside it; a sweep over <code>experiment.risk</code> \
             shows the cost cell by cell).</p>"
        );
    }
    let mut cells: Vec<&str> = Vec::new();
    for row in summary {
        if !cells.contains(&row.cell.as_str()) {
            cells.push(&row.cell);
        }
    }
    for cell in cells {
        if !cell.is_empty() {
            let _ = writeln!(html, "<h3>{}</h3>", escape(&readable_cell(cell)));
        }
        html.push_str("<table class=\"headline\">\n<tr><th>method</th>");
        for (_, title, _) in HEADLINE {
            let _ = write!(html, "<th>{title}</th>");
        }
        html.push_str("</tr>\n");
        for method in experiment.methods() {
            let _ = write!(html, "<tr><td>{}</td>", method.as_str());
            for (metric, _, digits) in HEADLINE {
                let row = summary
                    .iter()
                    .find(|s| s.cell == cell && s.method == method.as_str() && s.metric == metric);
                match row {
                    Some(s) if s.mean.is_finite() => {
                        let _ = write!(html, "<td>{:.digits$}", s.mean);
                        if s.ci95_low.is_finite() {
                            let _ = write!(
                                html,
                                "<br><small>[{:.digits$}, {:.digits$}]</small>",
                                s.ci95_low, s.ci95_high
                            );
                        }
                        html.push_str("</td>");
                    }
                    _ => html.push_str("<td>–</td>"),
                }
            }
            html.push_str("</tr>\n");
        }
        html.push_str("</table>\n");
        paired_table(html, experiment, cell, paired);
    }
}

/// The paired tables of one cell: each method against the reference
/// (nothing with a single method), then each method against itself at a
/// sweep axis's reference value (when the cell is off it).
fn paired_table(html: &mut String, experiment: &Experiment, cell: &str, paired: &[PairedRow]) {
    let mine = |p: &&PairedRow| p.cell == cell;
    if experiment.methods().len() >= 2 {
        let rows: Vec<(String, Vec<&PairedRow>)> = experiment
            .methods()
            .iter()
            .filter(|&m| m != experiment.reference())
            .map(|m| {
                let of_method = paired.iter().filter(mine).filter(|p| {
                    p.is_between_methods()
                        && p.reference == experiment.reference().as_str()
                        && p.method == m.as_str()
                });
                (m.as_str().to_string(), of_method.collect())
            })
            .collect();
        let header = format!("against {}", experiment.reference());
        paired_rows(html, &header, &rows);
    }
    let mut across: Vec<&str> = Vec::new();
    for p in paired
        .iter()
        .filter(mine)
        .filter(|p| !p.is_between_methods())
    {
        if !across.contains(&p.reference_cell.as_str()) {
            across.push(&p.reference_cell);
        }
    }
    for reference_cell in across {
        let rows: Vec<(String, Vec<&PairedRow>)> = experiment
            .methods()
            .iter()
            .map(|m| {
                let of_method = paired
                    .iter()
                    .filter(mine)
                    .filter(|p| p.reference_cell == reference_cell && p.method == m.as_str());
                (m.as_str().to_string(), of_method.collect())
            })
            .collect();
        // The reference cell in a line of its own: as the table's first
        // header it would widen that column past the page.
        let _ = writeln!(
            html,
            "<p>Each method against itself at <b>{}</b>, seed by seed:</p>",
            escape(&readable_cell(reference_cell))
        );
        paired_rows(html, "against itself", &rows);
    }
}

/// The per-point consistency check of each method that propagates, cell
/// by cell: the mean over the seeds of one point's NEES a run
/// (`nees_point`, independent across seeds) against the 95% band honest
/// covariances give that mean, `[χ²₃ₙ(0.025)/n, χ²₃ₙ(0.975)/n]` for n
/// seeds (docs/math.md §6.2, §6.6).
fn consistency(html: &mut String, summary: &[SummaryRow]) {
    let rows: Vec<&SummaryRow> = summary
        .iter()
        .filter(|r| r.metric == "nees_point" && r.n > 0 && r.mean.is_finite())
        .collect();
    if rows.is_empty() {
        return;
    }
    html.push_str(
        "<h2>Consistency</h2>\n<p>The points of a run share their views' pose errors, so a \
         run's ANEES has no χ² band (docs/math.md §6.6). One point a run does: its NEES is \
         independent from seed to seed, and with honest covariances its mean over n seeds \
         falls in the band below 95% of the time. Above it the method's covariances are too \
         small (over-confident), below it too large.</p>\n<table>\n<tr><th>cell</th>\
         <th>method</th><th>seeds</th><th>mean NEES of one point a run</th>\
         <th>95% band if honest</th><th>verdict</th></tr>\n",
    );
    for row in rows {
        let (verdict, band) = Consistency::of_mean_nees(row.mean, row.n);
        let _ = writeln!(
            html,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.2}</td><td>[{:.2}, {:.2}]</td>\
             <td>{}</td></tr>",
            escape(&readable_cell(&row.cell)),
            escape(&row.method),
            row.n,
            row.mean,
            band.0,
            band.1,
            verdict.as_str()
        );
    }
    html.push_str("</table>\n");
}

/// A cell label (`field=value;field=value`) as the page writes it, with room
/// to wrap after each `;`.
fn readable_cell(cell: &str) -> String {
    cell.replace(';', "; ")
}

/// One paired table: a row per label, each headline metric's mean per-seed
/// difference, interval and verdict.
fn paired_rows(html: &mut String, header: &str, rows: &[(String, Vec<&PairedRow>)]) {
    let _ = write!(html, "<table class=\"paired\">\n<tr><th>{header}</th>");
    for (_, title, _) in HEADLINE {
        let _ = write!(html, "<th>{title}</th>");
    }
    html.push_str("</tr>\n");
    for (label, of_label) in rows {
        let _ = write!(html, "<tr><td>{}</td>", escape(label));
        for (metric, _, digits) in HEADLINE {
            match of_label.iter().find(|p| p.metric == metric) {
                Some(p) if p.mean.is_finite() => {
                    let _ = write!(
                        html,
                        "<td class=\"{}\">{:+.digits$}",
                        p.verdict.as_str(),
                        p.mean
                    );
                    if p.ci95_low.is_finite() {
                        let _ = write!(
                            html,
                            "<br><small>[{:+.digits$}, {:+.digits$}]</small>",
                            p.ci95_low, p.ci95_high
                        );
                    }
                    let words = if p.n < 2 {
                        // No interval to judge by: say so, not "within noise".
                        crate::experiment::study::summary::NO_INTERVAL
                    } else {
                        verdict_words(p.verdict)
                    };
                    let _ = write!(html, "<br>{words}</td>");
                }
                _ => html.push_str("<td>–</td>"),
            }
        }
        html.push_str("</tr>\n");
    }
    html.push_str("</table>\n");
}

/// A verdict as the report writes it.
fn verdict_words(verdict: Verdict) -> &'static str {
    match verdict {
        Verdict::Better => "better",
        Verdict::Worse => "worse",
        Verdict::WithinNoise => "within noise",
    }
}

/// Writes `out/report.html` (staged).
pub fn write_report(
    out: &Path,
    experiment: &Experiment,
    study: &Study,
    inputs: &Inputs,
    charts: &[PathBuf],
) -> Result<()> {
    let html = render(experiment, study, inputs, charts)?;
    write_file(&out.join("report.html"), html.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each propagating method's mean `nees_point` is judged against the
    /// χ² band of its seeds (40 seeds: [2.29, 3.81]); a method that
    /// propagates none has no row.
    #[test]
    fn the_consistency_table_judges_each_mean_nees_against_its_band() {
        let row = |cell: &str, method: &str, n: usize, mean: f64| SummaryRow {
            cell: cell.into(),
            method: method.into(),
            metric: "nees_point".into(),
            n,
            mean,
            ci95_low: f64::NAN,
            ci95_high: f64::NAN,
        };
        let summary = [
            row("a=1", "unscented", 40, 2.52),
            row("a=0.5", "unscented", 40, 7.46),
            row("a=2", "unscented", 40, 0.77),
            row("a=1", "ray_update", 0, f64::NAN),
        ];
        let mut html = String::new();
        consistency(&mut html, &summary);
        let band = crate::uncertainty::consistency::anees_bounds(40, 3, 0.95);
        assert!(
            (band.0 - 2.289).abs() < 1e-3 && (band.1 - 3.805).abs() < 1e-3,
            "{band:?}"
        );
        for (cell, verdict) in [
            ("a=1", "consistent"),
            ("a=0.5", "over-confident"),
            ("a=2", "conservative"),
        ] {
            let line = html
                .lines()
                .find(|l| l.starts_with(&format!("<tr><td>{cell}</td>")))
                .unwrap_or_else(|| panic!("no row for {cell}: {html}"));
            assert!(
                line.contains("[2.29, 3.81]")
                    && line.ends_with(&format!("<td>{verdict}</td></tr>")),
                "{line}"
            );
        }
        assert!(!html.contains("ray_update"));
        let mut none = String::new();
        consistency(&mut none, &summary[3..]);
        assert!(none.is_empty());
    }

    #[test]
    fn map_settings_name_the_sweeps_that_vary_them() {
        let text = crate::experiment::portable_quickstart();
        let dir = tempfile::tempdir().unwrap();
        let load = |text: String| {
            let path = dir.path().join("e.toml");
            std::fs::write(&path, text).unwrap();
            Experiment::load(&path).unwrap()
        };
        let (opdf, rays) = map_settings(&load(text.clone()));
        assert_eq!(
            opdf,
            "beam pooling windows, surface samples on (gate model), risk level ε = 0.5"
        );
        assert_eq!(rays, "beam pooling off");
        let swept = text.replacen(
            "seed = 1",
            "seed = 1\nrisk = \"off\"\nbeam_pooling = \"off\"",
            1,
        ) + "[[sweep]]\nfield = \"experiment.risk\"\nvalues = [\"off\", 0.5]\n\
               [[sweep]]\nfield = \"experiment.beam_pooling\"\nvalues = [\"off\", \"windows\"]\n";
        let (opdf, rays) = map_settings(&load(swept));
        assert_eq!(
            opdf,
            "beam pooling off, surface samples on (gate model), risk level off (as the file sets \
             them; swept: experiment.risk, experiment.beam_pooling)"
        );
        assert_eq!(
            rays,
            "beam pooling off (as the file sets it; swept: experiment.beam_pooling)"
        );
    }

    #[test]
    fn a_pair_across_cells_names_its_reference_cell_above_the_table_not_in_its_header() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("e.toml");
        std::fs::write(&path, crate::experiment::portable_quickstart()).unwrap();
        let experiment = Experiment::load(&path).unwrap();
        let (cell, reference_cell) = (
            "experiment.risk=0.5;pose_error_scale=2",
            "experiment.risk=off;pose_error_scale=2",
        );
        let row = |metric: &str| PairedRow {
            cell: cell.into(),
            method: "unscented".into(),
            reference: "unscented".into(),
            reference_cell: reference_cell.into(),
            metric: metric.into(),
            n: 3,
            mean: -0.01,
            ci95_low: -0.02,
            ci95_high: 0.0,
            verdict: Verdict::Better,
        };
        let paired = [row("false_free_rate"), row("f1")];
        let mut html = String::new();
        paired_table(&mut html, &experiment, cell, &paired);
        assert!(
            html.contains("<b>experiment.risk=off; pose_error_scale=2</b>, seed by seed:</p>"),
            "{html}"
        );
        assert!(html.contains("<tr><th>against itself</th>"), "{html}");
        assert!(!html.contains("<th>against itself at"), "{html}");
        assert!(html.contains("<br>better</td>"), "{html}");
        // One seed has no interval: the table says so rather than "within
        // noise" (paired.csv's `within_noise` with n = 1, as documented).
        let single = [PairedRow {
            n: 1,
            ci95_low: f64::NAN,
            ci95_high: f64::NAN,
            verdict: Verdict::WithinNoise,
            ..row("f1")
        }];
        let mut html = String::new();
        paired_table(&mut html, &experiment, cell, &single);
        assert!(html.contains("<br>one seed: no interval</td>"), "{html}");
        assert!(!html.contains("within noise"), "{html}");
    }

    #[test]
    fn text_is_escaped() {
        assert_eq!(
            escape("<b>\"a\" & 'b'</b>"),
            "&lt;b&gt;&quot;a&quot; &amp; &#39;b&#39;&lt;/b&gt;"
        );
    }
}
