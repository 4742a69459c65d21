//! Draws the scaling study's chart (`bash benches/scaling.sh` runs it):
//!
//!     scaling_chart SCALING.csv SCALING.svg
//!
//! One column per varied axis; top row time, bottom row peak memory, one line
//! per measure, log-log.

use sigmap::experiment::charts::{panel_grid, Panel, Series};
use std::collections::BTreeMap;
use std::path::Path;

/// The axes in the study's order, with their x-axis labels.
const AXES: [(&str, &str); 5] = [
    ("resolution", "voxel edge (m)"),
    ("viewpoints", "viewpoints"),
    ("triangles", "scene triangles"),
    ("workspace", "workspace volume (m³)"),
    ("beams", "beams per scan"),
];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: scaling_chart SCALING.csv SCALING.svg");
        std::process::exit(2);
    }
    if let Err(e) = draw(Path::new(&args[1]), Path::new(&args[2])) {
        eprintln!("scaling_chart: {e}");
        std::process::exit(2);
    }
}

/// (axis, measure) -> points (x, seconds, peak MB).
type Table = BTreeMap<(String, String), Vec<(f64, f64, f64)>>;

fn draw(csv_path: &Path, svg_path: &Path) -> Result<(), String> {
    let mut reader =
        csv::Reader::from_path(csv_path).map_err(|e| format!("{}: {e}", csv_path.display()))?;
    let mut table = Table::new();
    for record in reader.records() {
        let record = record.map_err(|e| format!("{}: {e}", csv_path.display()))?;
        let number = |i: usize| -> Result<f64, String> {
            record
                .get(i)
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| format!("{}: bad number in {record:?}", csv_path.display()))
        };
        let key = (record[0].to_string(), record[2].to_string());
        table
            .entry(key)
            .or_default()
            .push((number(1)?, number(3)?, number(4)?));
    }
    // Every measure in every panel, in one order, so each keeps its colour
    // (a panel without it draws nothing for it).
    let mut measures: Vec<&String> = table.keys().map(|(_, m)| m).collect();
    measures.sort();
    measures.dedup();
    let series = |axis: &str, pick: fn(&(f64, f64, f64)) -> f64| -> Vec<Series> {
        measures
            .iter()
            .map(|measure| Series {
                name: (*measure).clone(),
                points: table
                    .get(&(axis.to_string(), (*measure).clone()))
                    .map_or(Vec::new(), |points| {
                        points.iter().map(|p| (p.0, pick(p))).collect()
                    }),
                intervals: Vec::new(),
            })
            .collect()
    };
    let times: Vec<Vec<Series>> = AXES.iter().map(|(a, _)| series(a, |p| p.1)).collect();
    let memory: Vec<Vec<Series>> = AXES.iter().map(|(a, _)| series(a, |p| p.2)).collect();
    let mut panels = Vec::new();
    for ((axis, label), lines) in AXES.iter().zip(&times) {
        panels.push(Panel {
            title: axis,
            x_label: label,
            y_label: "time (s)",
            log_x: true,
            log_y: true,
            series: lines,
        });
    }
    for ((axis, label), lines) in AXES.iter().zip(&memory) {
        panels.push(Panel {
            title: axis,
            x_label: label,
            y_label: "peak memory (MB)",
            log_x: true,
            log_y: true,
            series: lines,
        });
    }
    panel_grid(svg_path, AXES.len(), &panels).map_err(|e| e.to_string())
}
