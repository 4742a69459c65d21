//! `sigmap propagate`: one measurement through an uncertain chain, every method.

use super::PropagateArgs;
use crate::error::{Error, Result};
use crate::experiment::charts::figures::write_propagation_sweep;
use crate::uncertainty::chain::check_reach;
use crate::uncertainty::compare::{compare, log_space, sweep, MethodResult};
use crate::uncertainty::{read_chain_file, SigmaSet, UncertainPoint};
use std::path::PathBuf;
use std::time::Duration;

/// Most Monte Carlo draws one command makes (about a minute of work).
const MAX_SAMPLES: usize = 100_000_000;

/// `sigmap propagate`.
pub(crate) fn run(args: PropagateArgs) -> Result<()> {
    let (chain, file_point) = read_chain_file(&args.chain)?;
    if let Some(xyz) = &args.point {
        check_reach(xyz, "--point").map_err(Error::Usage)?;
    }
    let point = match (args.point, file_point) {
        (Some(xyz), Some(p)) => UncertainPoint {
            mean: xyz.into(),
            ..p
        },
        (Some(xyz), None) => UncertainPoint {
            mean: xyz.into(),
            covariance: Default::default(),
        },
        (None, Some(p)) => p,
        (None, None) => {
            return Err(Error::input(
                &args.chain,
                "the chain file has no [point]: add one, or give --point x,y,z",
            ))
        }
    };
    if !(2..=MAX_SAMPLES).contains(&args.samples) {
        return Err(Error::Usage(format!(
            "--samples {} must be between 2 and {MAX_SAMPLES}",
            args.samples
        )));
    }
    let sigma_set = match args.alpha {
        Some(alpha) => SigmaSet::scaled(alpha, args.beta, args.kappa)
            .map_err(|e| Error::Usage(format!("--{e}")))?,
        None => SigmaSet::Paper,
    };
    if args.sweep {
        return run_sweep(&args, &chain, &point, sigma_set);
    }
    let comparison = compare(
        &chain,
        &point,
        sigma_set,
        args.samples,
        args.seed,
        Duration::from_millis(20),
    );
    if args.json {
        let text = serde_json::to_string_pretty(&comparison)
            .map_err(|e| Error::Internal(e.to_string()))?;
        println!("{text}");
        return Ok(());
    }
    println!(
        "{} links, {} sigma points, Monte Carlo {} draws (seed {})",
        chain.links.len(),
        comparison.sigma_points,
        comparison.samples,
        comparison.seed
    );
    let m = &comparison.methods;
    for (name, r) in [
        ("blind", &m.blind),
        ("jacobian", &m.jacobian),
        ("unscented", &m.unscented),
        ("monte_carlo", &m.monte_carlo),
    ] {
        print_method(name, r);
    }
    Ok(())
}

fn print_method(name: &str, r: &MethodResult) {
    let sd: Vec<String> = (0..3)
        .map(|i| format!("{:.3e}", r.covariance[i][i].sqrt()))
        .collect();
    println!(
        "{name:<12} mean [{:.6}, {:.6}, {:.6}]  sd [{}] m  {:.3} µs/point (+{:.2} µs setup)",
        r.mean[0],
        r.mean[1],
        r.mean[2],
        sd.join(", "),
        r.micros,
        r.setup_micros
    );
}

fn run_sweep(
    args: &PropagateArgs,
    chain: &crate::uncertainty::UncertainChain,
    point: &UncertainPoint,
    sigma_set: SigmaSet,
) -> Result<()> {
    if !(2..=1000).contains(&args.sweep_points) {
        return Err(Error::Usage(format!(
            "--sweep-points {} must be between 2 and 1000",
            args.sweep_points
        )));
    }
    if args.samples.saturating_mul(args.sweep_points) > MAX_SAMPLES {
        return Err(Error::Usage(format!(
            "--samples {} x --sweep-points {} draws exceed {MAX_SAMPLES}",
            args.samples, args.sweep_points
        )));
    }
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("results").join(format!("{}_sweep", crate::files::stem(&args.chain)))
    });
    let rows = sweep(
        chain,
        point,
        sigma_set,
        &log_space(0.001, 0.2, args.sweep_points),
        args.samples,
        args.seed,
    );
    write_propagation_sweep(&out, &rows, args.samples)?;
    eprintln!(
        "wrote {}/sweep.csv and sweep.svg ({} rotation sigmas, Monte Carlo {} draws each)",
        out.display(),
        args.sweep_points,
        args.samples
    );
    Ok(())
}
