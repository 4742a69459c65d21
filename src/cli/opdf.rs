//! `sigmap opdf`: draw the occupancy profile for several sigmas (the paper's
//! figures 1 and 6), so anyone can see what the model puts along a beam.

use super::OpdfArgs;
use crate::error::Result;
use crate::experiment::charts::figures::write_opdf_figures;
use std::path::PathBuf;

/// `sigmap opdf`.
pub(crate) fn run(args: OpdfArgs) -> Result<()> {
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results").join("opdf"));
    write_opdf_figures(&out, args.thickness, args.range)
        .map_err(|e| e.context("--thickness, --range: "))?;
    eprintln!(
        "wrote {}/opdf_fig1.svg, opdf_fig6.svg and opdf.csv",
        out.display()
    );
    Ok(())
}
