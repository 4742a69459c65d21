//! `sigmap opdf`: draw the occupancy profile for several sigmas (the paper's
//! figures 1 and 6), so anyone can see what the model puts along a beam.

use super::OpdfArgs;
use crate::error::{Error, Result};
use crate::files::write_folder;
use crate::mapping::opdf::OpdfParams;
use crate::plot::{panels, Panel, Series};
use std::fmt::Write as _;
use std::path::PathBuf;

/// `sigmap opdf`.
pub(crate) fn run(args: OpdfArgs) -> Result<()> {
    let (delta, r) = (args.thickness, args.range);
    if !(delta.is_finite() && delta > 0.0 && r.is_finite() && r > 10.0 * delta) {
        return Err(Error::Usage(
            "--thickness must be positive and --range more than ten thicknesses".into(),
        ));
    }
    let params = OpdfParams::new(delta);
    let lambdas: Vec<f64> = (0..=2000)
        .map(|i| -0.1 * r + i as f64 * (1.3 * r) / 2000.0)
        .collect();
    let curve = |name: String, sigma: f64, sigma_o: f64| Series {
        intervals: Vec::new(),
        name,
        points: lambdas
            .iter()
            .map(|&l| (l, params.extended(l, r, sigma, sigma_o)))
            .collect(),
    };
    let fig1: Vec<Series> = [0.5, 1.0, 2.0, 4.0]
        .iter()
        .map(|k| curve(format!("σ = {k}Δ"), k * delta, 0.0))
        .collect();
    let fig6: Vec<Series> = [0.0, 3.0, 10.0]
        .iter()
        .map(|k| curve(format!("σ_o = {k}Δ (σ = Δ)"), delta, k * delta))
        .collect();
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results").join("opdf"));
    write_folder(&out, |dir| {
        let mut csv = String::from("figure,curve,lambda,p\n");
        for (figure, series) in [("fig1", &fig1), ("fig6", &fig6)] {
            for s in series.iter() {
                for (l, p) in &s.points {
                    let _ = writeln!(csv, "{figure},{},{l:?},{p:?}", s.name);
                }
            }
        }
        std::fs::write(dir.join("opdf.csv"), csv)
            .map_err(|e| Error::io(dir.join("opdf.csv"), e))?;
        let x_label = "λ, distance along the beam from the sensor (m)";
        panels(
            &dir.join("opdf_fig1.svg"),
            &[Panel {
                title: &format!("OPDF for a surface at {r} m (Δ = {delta} m), exact origin"),
                x_label,
                y_label: "occupancy probability",
                log_x: false,
                log_y: false,
                series: &fig1,
            }],
        )?;
        panels(
            &dir.join("opdf_fig6.svg"),
            &[Panel {
                title: "extended OPDF: uncertain sensor origin",
                x_label,
                y_label: "occupancy probability",
                log_x: false,
                log_y: false,
                series: &fig6,
            }],
        )
    })?;
    eprintln!(
        "wrote {}/opdf_fig1.svg, opdf_fig6.svg and opdf.csv",
        out.display()
    );
    Ok(())
}
