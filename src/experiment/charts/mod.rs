//! SVG charts (plotters), shared by every command that draws.
//!
//! Log axes are drawn by plotting `log10` of the data on a linear axis and
//! labelling each tick with `10^tick`, so one code path serves both kinds of axes.

pub mod figures;
pub mod results;
pub mod slice;

use crate::error::{Error, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// One named line of a chart.
pub struct Series {
    /// Legend label.
    pub name: String,
    /// Points `(x, y)`; non-finite values (and non-positive ones on log axes) are skipped.
    pub points: Vec<(f64, f64)>,
    /// Error bars `(x, low, high)`, drawn as vertical segments (may be empty).
    pub intervals: Vec<(f64, f64, f64)>,
}

/// A chart panel: title, axis labels, axis kinds, and its lines.
pub struct Panel<'a> {
    /// Title above the panel.
    pub title: &'a str,
    /// X axis label.
    pub x_label: &'a str,
    /// Y axis label.
    pub y_label: &'a str,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The lines.
    pub series: &'a [Series],
}

/// Tableau's ten categorical colours; lines past the tenth repeat them
/// dashed, so twenty lines are told apart ([`LineStyle::of`]).
const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// A panel with more lines than this gets its legend in a strip below the
/// panels: a box inside the plot would cover the lines.
pub const IN_PLOT_LEGEND: usize = 6;

/// How line `k` of a figure is drawn: its colour, and dashed from the
/// eleventh line on.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LineStyle {
    colour: RGBColor,
    dashed: bool,
}

impl LineStyle {
    fn of(k: usize) -> Self {
        Self {
            colour: COLOURS[k % COLOURS.len()],
            dashed: (k / COLOURS.len()) % 2 == 1,
        }
    }
}

fn transform(v: f64, log: bool) -> Option<f64> {
    match (log, v.is_finite()) {
        (_, false) => None,
        (true, true) if v <= 0.0 => None,
        (true, true) => Some(v.log10()),
        (false, true) => Some(v),
    }
}

fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(v), h.max(v))
    });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if log {
        0.15
    } else {
        0.05 * (hi - lo).max(1e-12)
    };
    (lo - pad, hi + pad)
}

/// Each error bar as a two-point line.
fn bars_as_lines(bars: &[Vec<(f64, f64, f64)>]) -> Vec<Vec<(f64, f64)>> {
    bars.iter()
        .flatten()
        .map(|&(x, lo, hi)| vec![(x, lo), (x, hi)])
        .collect()
}

/// The corner of the plot whose legend box (`series` lines of up to
/// `longest` characters, sized as plotters draws it on a 560 × 420 panel)
/// covers the fewest samples of the drawn `lines` (each segment sampled at
/// ten points); ties go to the upper left, then upper right, lower left,
/// lower right.
fn legend_corner<'a>(
    lines: impl Iterator<Item = &'a [(f64, f64)]>,
    ((x0, x1), (y0, y1)): ((f64, f64), (f64, f64)),
    series: usize,
    longest: usize,
) -> SeriesLabelPosition {
    let width = ((longest as f64 * 6.5 + 45.0) / 470.0).min(1.0) * (x1 - x0);
    let height = ((series as f64 * 15.0 + 12.0) / 330.0).min(1.0) * (y1 - y0);
    let boxes = [
        (SeriesLabelPosition::UpperLeft, x0, y1 - height),
        (SeriesLabelPosition::UpperRight, x1 - width, y1 - height),
        (SeriesLabelPosition::LowerLeft, x0, y0),
        (SeriesLabelPosition::LowerRight, x1 - width, y0),
    ];
    let mut covered = [0usize; 4];
    for line in lines {
        let samples = line.windows(2).flat_map(|w| {
            (0..10).map(move |i| {
                let t = i as f64 / 10.0;
                (
                    w[0].0 + t * (w[1].0 - w[0].0),
                    w[0].1 + t * (w[1].1 - w[0].1),
                )
            })
        });
        for (x, y) in samples.chain(line.last().copied()) {
            for (count, &(_, bx, by)) in covered.iter_mut().zip(&boxes) {
                if (bx..=bx + width).contains(&x) && (by..=by + height).contains(&y) {
                    *count += 1;
                }
            }
        }
    }
    let best = (0..4).min_by_key(|&i| (covered[i], i)).unwrap_or(0);
    match best {
        1 => SeriesLabelPosition::UpperRight,
        2 => SeriesLabelPosition::LowerLeft,
        3 => SeriesLabelPosition::LowerRight,
        _ => SeriesLabelPosition::UpperLeft,
    }
}

/// A tick's label: the value on a linear axis, and on a log axis (where `v`
/// is its `log10`) the value in plain digits, to two significant digits
/// below 100 and whole from 100 on, from 0.01 to 10 000; in scientific
/// notation beyond.
fn label(v: f64, log: bool) -> String {
    if !log {
        return format!("{v:.3}");
    }
    let x = 10f64.powf(v);
    if (0.01..10_000.0).contains(&x.abs()) {
        let decimals = (1.0 - x.abs().log10().floor()).max(0.0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.1e}")
    }
}

/// Writes side-by-side panels into an SVG file (staged, then renamed).
pub fn panels(path: &Path, panels: &[Panel]) -> Result<()> {
    panel_grid(path, panels.len(), panels)
}

/// Writes panels in rows of `columns` into an SVG file (staged, then renamed).
/// Each panel names its lines in a box where they leave room; when a panel
/// has more than [`IN_PLOT_LEGEND`] lines, the figure names them all once in
/// a strip below the panels instead, and a name keeps its style in every
/// panel.
pub fn panel_grid(path: &Path, columns: usize, panels: &[Panel]) -> Result<()> {
    let mut svg = String::new();
    draw_panels(&mut svg, path, columns.max(1), panels)?;
    crate::files::write_file(path, svg.as_bytes())
}

/// The names of a figure's lines in order of first appearance, if some
/// panel has too many lines for a legend inside it.
fn shared_key(panels: &[Panel]) -> Option<Vec<String>> {
    if panels.iter().all(|p| p.series.len() <= IN_PLOT_LEGEND) {
        return None;
    }
    let mut names: Vec<String> = Vec::new();
    for series in panels.iter().flat_map(|p| p.series) {
        if !names.contains(&series.name) {
            names.push(series.name.clone());
        }
    }
    Some(names)
}

/// The strip below the panels that names a figure's lines: entries of a
/// common width (px), `per_row` to a row, and its height (px).
struct KeyLayout {
    entry: u32,
    per_row: usize,
    height: u32,
}

impl KeyLayout {
    /// The strip of `key` across `width` pixels.
    fn of(key: &[String], width: u32) -> Self {
        let longest = key.iter().map(|n| n.chars().count()).max().unwrap_or(0) as u32;
        let entry = KEY_SWATCH + 7 * longest + 24;
        let per_row = (width.saturating_sub(20) / entry).max(1) as usize;
        let rows = key.len().div_ceil(per_row) as u32;
        Self {
            entry,
            per_row,
            height: 20 * rows + 20,
        }
    }
}

/// Pixels of a key entry's line sample and the gap after it.
const KEY_SWATCH: u32 = 34;

fn draw_panels(svg: &mut String, path: &Path, columns: usize, panels: &[Panel]) -> Result<()> {
    let rows = panels.len().div_ceil(columns).max(1);
    let width = 560 * columns as u32;
    let key = shared_key(panels).map(|key| {
        let layout = KeyLayout::of(&key, width);
        (key, layout)
    });
    let strip = key.as_ref().map_or(0, |(_, layout)| layout.height);
    let size = (width, 420 * rows as u32 + strip);
    let root = SVGBackend::with_string(svg, size).into_drawing_area();
    let err = |e: &dyn std::fmt::Display| Error::input(path, format!("cannot draw the chart: {e}"));
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (plots, below) = root.split_vertically(420 * rows as u32);
    let areas = plots.split_evenly((rows, columns));
    let names = key.as_ref().map(|(names, _)| &names[..]);
    for (area, panel) in areas.iter().zip(panels) {
        draw_panel(area, panel, names).map_err(|e| err(&e))?;
    }
    if let Some((names, layout)) = &key {
        draw_key(&below, names, layout).map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))
}

/// The shared legend: each name after a sample of its line (two dashes
/// for a dashed one), in `layout`'s rows.
fn draw_key(
    strip: &DrawingArea<SVGBackend, Shift>,
    key: &[String],
    layout: &KeyLayout,
) -> std::result::Result<(), String> {
    let text = |e: &dyn std::fmt::Display| e.to_string();
    let style = ("sans-serif", 13).into_font().color(&BLACK);
    for (k, name) in key.iter().enumerate() {
        let (x, y) = (
            20 + (layout.entry as usize * (k % layout.per_row)) as i32,
            10 + 20 * (k / layout.per_row) as i32,
        );
        let line = LineStyle::of(k);
        let dashes: &[(i32, i32)] = if line.dashed {
            &[(0, 10), (16, 26)]
        } else {
            &[(0, 26)]
        };
        for &(from, to) in dashes {
            let dash = vec![(x + from, y + 8), (x + to, y + 8)];
            strip
                .draw(&PathElement::new(dash, line.colour.stroke_width(2)))
                .map_err(|e| text(&e))?;
        }
        strip
            .draw(&Text::new(
                name.clone(),
                (x + KEY_SWATCH as i32, y),
                style.clone(),
            ))
            .map_err(|e| text(&e))?;
    }
    Ok(())
}

/// A panel's series on its axes (log axes as log10): per series its line
/// points and its interval bars `(x, low, high)`; points a log axis cannot
/// show are left out.
#[allow(clippy::type_complexity)]
fn panel_points(panel: &Panel) -> (Vec<Vec<(f64, f64)>>, Vec<Vec<(f64, f64, f64)>>) {
    let lines = panel
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter_map(|&(x, y)| {
                    Some((transform(x, panel.log_x)?, transform(y, panel.log_y)?))
                })
                .collect()
        })
        .collect();
    let bars = panel
        .series
        .iter()
        .map(|s| {
            s.intervals
                .iter()
                .filter_map(|&(x, lo, hi)| {
                    Some((
                        transform(x, panel.log_x)?,
                        transform(lo, panel.log_y)?,
                        transform(hi, panel.log_y)?,
                    ))
                })
                .collect()
        })
        .collect();
    (lines, bars)
}

type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// One panel: axes fitted to its data, its series, and its legend where the
/// lines leave room; with a figure's shared `key`, each line takes the style
/// of its name there and the panel draws no legend of its own.
fn draw_panel(
    area: &DrawingArea<SVGBackend, Shift>,
    panel: &Panel,
    key: Option<&[String]>,
) -> std::result::Result<(), String> {
    let text = |e: &dyn std::fmt::Display| e.to_string();
    let (lines, bars) = panel_points(panel);
    let xs = range(lines.iter().flatten().map(|p| p.0), panel.log_x);
    let ys = range(
        lines
            .iter()
            .flatten()
            .map(|p| p.1)
            .chain(bars.iter().flatten().flat_map(|b| [b.1, b.2])),
        panel.log_y,
    );
    let mut chart = ChartBuilder::on(area)
        .caption(panel.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(xs.0..xs.1, ys.0..ys.1)
        .map_err(|e| text(&e))?;
    let (log_x, log_y) = (panel.log_x, panel.log_y);
    chart
        .configure_mesh()
        .x_desc(panel.x_label)
        .y_desc(panel.y_label)
        .x_label_formatter(&|v| label(*v, log_x))
        .y_label_formatter(&|v| label(*v, log_y))
        .draw()
        .map_err(|e| text(&e))?;
    for (k, (series, points)) in panel.series.iter().zip(&lines).enumerate() {
        let style = key
            .and_then(|key| key.iter().position(|name| *name == series.name))
            .unwrap_or(k);
        let line = LineStyle::of(style);
        draw_series(&mut chart, line, series, points, &bars[k]).map_err(|e| text(&e))?;
    }
    if key.is_some() {
        return Ok(());
    }
    let bar_lines = bars_as_lines(&bars);
    let drawn = lines.iter().chain(&bar_lines).map(|l| &l[..]);
    let longest = panel
        .series
        .iter()
        .map(|s| s.name.chars().count())
        .max()
        .unwrap_or(0);
    let corner = legend_corner(drawn, (xs, ys), panel.series.len(), longest);
    chart
        .configure_series_labels()
        .position(corner)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| text(&e))
}

/// A series of a panel in `line`'s style: its interval bars, its line
/// (named in the legend) and, for a few points, dots.
fn draw_series(
    chart: &mut Chart,
    line: LineStyle,
    series: &Series,
    points: &[(f64, f64)],
    bars: &[(f64, f64, f64)],
) -> std::result::Result<(), String> {
    let text = |e: &dyn std::fmt::Display| e.to_string();
    let colour = line.colour;
    if points.is_empty() && bars.is_empty() {
        // Nothing to draw (nor to name); its colour stays its own.
        return Ok(());
    }
    chart
        .draw_series(
            bars.iter().map(|&(x, lo, hi)| {
                PathElement::new(vec![(x, lo), (x, hi)], colour.stroke_width(1))
            }),
        )
        .map_err(|e| text(&e))?;
    let labelled = if line.dashed {
        chart.draw_series(DashedLineSeries::new(
            points.iter().copied(),
            6,
            4,
            colour.stroke_width(2),
        ))
    } else {
        chart.draw_series(LineSeries::new(
            points.iter().copied(),
            colour.stroke_width(2),
        ))
    };
    labelled
        .map_err(|e| text(&e))?
        .label(series.name.clone())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
    if points.len() <= 60 {
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(|e| text(&e))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_ticks_read_as_plain_numbers_within_four_decades() {
        let tick = |x: f64| label(x.log10(), true);
        assert_eq!(tick(3.16), "3.2");
        assert_eq!(tick(31.6), "32");
        assert_eq!(tick(2120.5), "2121");
        assert_eq!(tick(0.0316), "0.032");
        assert_eq!(tick(1.0), "1.0");
        assert_eq!(tick(250_000.0), "2.5e5");
        assert_eq!(tick(0.001), "1.0e-3");
        assert_eq!(label(0.25, false), "0.250");
    }

    #[test]
    fn twenty_lines_are_drawn_in_twenty_styles() {
        let styles: Vec<LineStyle> = (0..20).map(LineStyle::of).collect();
        for (i, a) in styles.iter().enumerate() {
            for b in &styles[..i] {
                assert_ne!(a, b);
            }
        }
    }

    /// The `y` of the SVG text element that reads exactly `name`.
    fn text_y(svg: &str, name: &str) -> f64 {
        let end = svg
            .find(&format!(">\n{name}\n</text>"))
            .unwrap_or_else(|| panic!("no text {name}"));
        let open = svg[..end].rfind("<text").unwrap();
        let y = &svg[open..end];
        let at = y.find(" y=\"").unwrap() + 4;
        y[at..at + y[at..].find('"').unwrap()].parse().unwrap()
    }

    #[test]
    fn a_crowded_panel_names_its_lines_below_the_plots_and_a_sparse_one_inside() {
        let lines = |n: usize| -> Vec<Series> {
            (0..n)
                .map(|k| Series {
                    name: format!("line {k}"),
                    points: vec![(0.0, k as f64), (1.0, k as f64 + 0.5)],
                    intervals: Vec::new(),
                })
                .collect()
        };
        let draw = |series: &[Series]| {
            let panel = Panel {
                title: "t",
                x_label: "x",
                y_label: "y",
                log_x: false,
                log_y: false,
                series,
            };
            let mut svg = String::new();
            draw_panels(&mut svg, Path::new("t.svg"), 1, &[panel]).unwrap();
            svg
        };
        let height = |svg: &str| -> f64 {
            let at = svg.find("height=\"").unwrap() + 8;
            svg[at..at + svg[at..].find('"').unwrap()].parse().unwrap()
        };
        let sparse = draw(&lines(IN_PLOT_LEGEND));
        assert_eq!(height(&sparse), 420.0);
        for k in 0..IN_PLOT_LEGEND {
            assert!(text_y(&sparse, &format!("line {k}")) < 420.0);
        }
        let crowded = draw(&lines(IN_PLOT_LEGEND + 6));
        assert!(height(&crowded) > 420.0);
        for k in 0..IN_PLOT_LEGEND + 6 {
            let y = text_y(&crowded, &format!("line {k}"));
            assert!((420.0..height(&crowded)).contains(&y), "line {k} at {y}");
        }
    }

    #[test]
    fn the_legend_goes_where_the_lines_are_not() {
        let frame = ((0.0, 2.0), (0.0, 1.0));
        let corner = |line: &[(f64, f64)]| legend_corner([line].into_iter(), frame, 4, 30);
        // Falling from the upper left: the upper right is empty.
        assert_eq!(
            corner(&[(0.0, 1.0), (2.0, 0.0)]),
            SeriesLabelPosition::UpperRight
        );
        // Rising from the lower left: the upper left is empty.
        assert_eq!(
            corner(&[(0.0, 0.0), (2.0, 1.0)]),
            SeriesLabelPosition::UpperLeft
        );
        // Along the top: a lower corner.
        assert_eq!(
            corner(&[(0.0, 0.95), (2.0, 0.95)]),
            SeriesLabelPosition::LowerLeft
        );
    }
}
