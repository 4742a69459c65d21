//! `slice.svg` of `sigmap run`: a horizontal slice through the objects, each
//! map against the truth.

use crate::error::{Error, Result};
use crate::eval::scores::UNKNOWN_BAND;
use crate::experiment::RunMethod;
use crate::geometry::Point3;
use crate::mapping::Octree;
use crate::sim::scene::Bounds;
use plotters::prelude::*;
use std::path::Path;

/// The height of the slice: halfway between the lowest and the highest truly
/// occupied cell (through the objects rather than the floor), on a cell centre.
pub fn slice_height(truth: &Octree) -> f64 {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    truth.visit_leaves(|leaf| {
        if leaf.value >= 0.0 {
            let z = truth.center(&leaf.key, leaf.depth).z;
            lo = lo.min(z);
            hi = hi.max(z);
        }
    });
    if !lo.is_finite() {
        return 0.0;
    }
    let res = truth.resolution();
    (((lo + hi) / 2.0 / res).floor() + 0.5) * res
}

/// Most cells drawn per axis of a slice panel.
const MAX_SLICE_CELLS: f64 = 160.0;

/// `slice.svg`: a horizontal slice at height `z` of each map against the
/// truth: correct occupied, correct free, false-free, false-occupied, unknown.
pub fn plot_slice(
    path: &Path,
    truth: &Octree,
    maps: &[(RunMethod, &Octree)],
    workspace: &Bounds,
    z: f64,
) -> Result<()> {
    let mut svg = String::new();
    draw_slice(&mut svg, path, truth, maps, workspace, z)?;
    crate::files::write_file(path, svg.as_bytes())
}

/// The cells of a slice: `counts` cells of edge `cell` from `min` at height `z`.
struct SliceGrid {
    min: (f64, f64),
    counts: (usize, usize),
    cell: f64,
    z: f64,
}

/// The slice's cells the truth knows, by class (occupied and correct, free
/// and correct, false-free, false-occupied, unknown; `classes` lists), as
/// runs along x of equal class: `(x, y, width)` from the run's lower-left
/// corner. One rectangle per run keeps the chart small.
fn slice_classes(
    truth: &Octree,
    map: &Octree,
    grid: &SliceGrid,
    classes: usize,
) -> Vec<Vec<(f64, f64, f64)>> {
    let mut runs: Vec<Vec<(f64, f64, f64)>> = vec![Vec::new(); classes];
    let cell = grid.cell;
    for j in 0..grid.counts.1 {
        // The run under way: its class, first column and length.
        let mut open: Option<(usize, usize, usize)> = None;
        let y = grid.min.1 + j as f64 * cell;
        let mut close = |run: Option<(usize, usize, usize)>| {
            if let Some((class, first, length)) = run {
                let x = grid.min.0 + first as f64 * cell;
                runs[class].push((x, y, length as f64 * cell));
            }
        };
        for i in 0..grid.counts.0 {
            let p = Point3::new(
                grid.min.0 + (i as f64 + 0.5) * cell,
                grid.min.1 + (j as f64 + 0.5) * cell,
                grid.z,
            );
            let class = truth.value_at(&p).map(|t| slice_class(t, map.value_at(&p)));
            match (open, class) {
                (Some((c, first, length)), Some(k)) if c == k && first + length == i => {
                    open = Some((c, first, length + 1));
                }
                (_, class) => {
                    close(open);
                    open = class.map(|k| (k, i, 1));
                }
            }
        }
        close(open);
    }
    runs
}

/// The class of a cell whose truth is `t` and which the map holds as
/// `value`: 0 occupied and correct, 1 free and correct, 2 false-free,
/// 3 false-occupied, 4 unknown.
fn slice_class(t: f32, value: Option<f32>) -> usize {
    match value {
        Some(l) if l >= UNKNOWN_BAND => {
            if t >= 0.0 {
                0
            } else {
                3
            }
        }
        Some(l) if l <= -UNKNOWN_BAND => {
            if t >= 0.0 {
                2
            } else {
                1
            }
        }
        _ => 4,
    }
}

/// The slice's legend: a swatch (outlined, so that a pale class shows)
/// and a name per class, in a row.
fn draw_legend(
    strip: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    colours: &[(&str, RGBColor)],
) -> std::result::Result<(), String> {
    let text = |e: &dyn std::fmt::Display| e.to_string();
    let style = ("sans-serif", 14).into_font().color(&BLACK);
    let mut x = 20;
    for (name, colour) in colours {
        strip
            .draw(&Rectangle::new([(x, 12), (x + 14, 26)], colour.filled()))
            .map_err(|e| text(&e))?;
        strip
            .draw(&Rectangle::new(
                [(x, 12), (x + 14, 26)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| text(&e))?;
        strip
            .draw(&Text::new(name.to_string(), (x + 20, 12), style.clone()))
            .map_err(|e| text(&e))?;
        x += 30 + 8 * name.len() as i32;
    }
    Ok(())
}

fn draw_slice(
    svg: &mut String,
    path: &Path,
    truth: &Octree,
    maps: &[(RunMethod, &Octree)],
    workspace: &Bounds,
    z: f64,
) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| Error::input(path, format!("cannot draw the slice: {e}"));
    let res = truth.resolution();
    let (nx, ny) = (
        ((workspace.max.x - workspace.min.x) / res).ceil(),
        ((workspace.max.y - workspace.min.y) / res).ceil(),
    );
    // A panel is ~400 px: beyond 160 cells per axis, draw every `step`-th
    // cell (its centre's class) as a step x step block, so the file stays
    // small whatever the workspace.
    let step = (nx.max(ny) / MAX_SLICE_CELLS).ceil().max(1.0);
    let (nx, ny) = ((nx / step).ceil() as usize, (ny / step).ceil() as usize);
    let cell = res * step;
    let width = 460 * maps.len().max(1) as u32;
    let root = SVGBackend::with_string(svg, (width, 540)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let colours = [
        ("occupied, correct", RGBColor(30, 30, 30)),
        ("free, correct", RGBColor(205, 225, 245)),
        ("false-free", RGBColor(220, 30, 30)),
        ("false-occupied", RGBColor(245, 150, 20)),
        ("unknown", RGBColor(200, 200, 200)),
    ];
    // The legend in a strip of its own below the panels: it covers no data.
    let (panels, strip) = root.split_vertically(500);
    draw_legend(&strip, &colours).map_err(|e| err(&e))?;
    for (area, (method, map)) in panels.split_evenly((1, maps.len().max(1))).iter().zip(maps) {
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("{method}: slice at z = {z:.3} m"),
                ("sans-serif", 16),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(55)
            .build_cartesian_2d(
                workspace.min.x..workspace.max.x,
                workspace.min.y..workspace.max.y,
            )
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m, map frame)")
            .y_desc("y (m)")
            .draw()
            .map_err(|e| err(&e))?;
        let grid = SliceGrid {
            min: (workspace.min.x, workspace.min.y),
            counts: (nx, ny),
            cell,
            z,
        };
        let cells = slice_classes(truth, map, &grid, colours.len());
        for ((_, colour), runs) in colours.iter().zip(cells) {
            let colour = *colour;
            chart
                .draw_series(
                    runs.into_iter().map(|(x, y, w)| {
                        Rectangle::new([(x, y), (x + w, y + cell)], colour.filled())
                    }),
                )
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))
}
