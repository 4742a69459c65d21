//! The paper's figures as files: the occupancy profile along a beam
//! (Payeur's figures 1 and 6; docs/math.md §4.3–4.4) and the comparison of
//! the propagators against Monte Carlo over rotation sigmas.

use crate::error::{metres, Error, Result};
use crate::experiment::charts::{panels, Panel, Series};
use crate::files::write_folder;
use crate::mapping::octree::{check_span, span, RESOLUTIONS};
use crate::mapping::opdf::OpdfParams;
use crate::uncertainty::compare::SweepRow;
use std::fmt::Write as _;
use std::path::Path;

/// Writes `opdf.csv`, `opdf_fig1.svg` (exact origin, σ from Δ/2 to 4Δ) and
/// `opdf_fig6.svg` (σ = Δ, origin σ_o from 0 to 10Δ) into the folder `out`
/// for a surface of thickness `delta` at range `r` (staged, then renamed).
pub fn write_opdf_figures(out: &Path, delta: f64, r: f64) -> Result<()> {
    let (delta_m, r_m) = (metres(delta), metres(r));
    if !(RESOLUTIONS.contains(&delta) && r.is_finite() && r > 10.0 * delta) {
        return Err(Error::Usage(format!(
            "a surface thickness of {delta_m} m at range {r_m} m: the thickness is a voxel edge \
             (0.001 to 1 m) and the range more than ten thicknesses"
        )));
    }
    check_span(r, delta).map_err(|_| {
        Error::Usage(format!(
            "a surface at range {r_m} m lies outside any map of {delta_m} m voxels (±{} m)",
            span(delta)
        ))
    })?;
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
    write_folder(out, |dir| {
        let mut csv = String::from("figure,curve,lambda,p\n");
        for (figure, series) in [("fig1", &fig1), ("fig6", &fig6)] {
            for s in series {
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
    })
}

/// Writes `sweep.csv` and `sweep.svg` (each method's covariance error and
/// KL divergence against Monte Carlo, with Monte Carlo's own noise) into the
/// folder `out` (staged, then renamed).
pub fn write_propagation_sweep(out: &Path, rows: &[SweepRow], samples: usize) -> Result<()> {
    write_folder(out, |dir| {
        write_sweep_csv(&dir.join("sweep.csv"), rows)?;
        plot_sweep(&dir.join("sweep.svg"), rows, samples)
    })
}

fn write_sweep_csv(path: &Path, rows: &[SweepRow]) -> Result<()> {
    let mut w = csv::Writer::from_path(path).map_err(|e| Error::io(path, e.into()))?;
    for row in rows {
        w.serialize(row).map_err(|e| Error::io(path, e.into()))?;
    }
    w.flush().map_err(|e| Error::io(path, e))
}

fn plot_sweep(path: &Path, rows: &[SweepRow], samples: usize) -> Result<()> {
    let series = |metric: fn(&SweepRow) -> f64| -> Vec<Series> {
        let mut out: Vec<Series> = ["blind", "jacobian", "unscented"]
            .iter()
            .map(|m| Series {
                intervals: Vec::new(),
                name: m.to_string(),
                points: rows
                    .iter()
                    .filter(|r| r.method == *m)
                    .map(|r| (r.rotation_sigma, metric(r)))
                    .collect(),
            })
            .collect();
        out.push(Series {
            intervals: Vec::new(),
            name: format!("MC noise (N={samples})"),
            points: rows
                .iter()
                .filter(|r| r.method == "jacobian")
                .map(|r| (r.rotation_sigma, r.mc_relative_se))
                .collect(),
        });
        out
    };
    let frob = series(|r| r.relative_frobenius);
    let mut kl = series(|r| r.kl_divergence);
    kl.pop();
    panels(
        path,
        &[
            Panel {
                title: "covariance error vs Monte Carlo",
                x_label: "rotation sigma of every link (rad)",
                y_label: "relative Frobenius error",
                log_x: true,
                log_y: true,
                series: &frob,
            },
            Panel {
                title: "KL(Monte Carlo || method)",
                x_label: "rotation sigma of every link (rad)",
                y_label: "KL divergence (nats)",
                log_x: true,
                log_y: true,
                series: &kl,
            },
        ],
    )
}
