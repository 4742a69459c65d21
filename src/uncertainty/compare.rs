//! Every propagator on one chain and point, timed: what `sigmap propagate`
//! prints, and the rotation-sigma sweep that reproduces the paper's comparison.

use super::chain::{Gaussian3, UncertainChain, UncertainPoint};
use super::consistency::{forstner_distance, kl_divergence, relative_frobenius};
use super::{
    BlindPropagator, JacobianPropagator, MonteCarloPropagator, Propagator, SigmaSet,
    UnscentedPropagator,
};
use crate::geometry::Matrix6;
use serde::Serialize;
use std::hint::black_box;
use std::time::{Duration, Instant};

/// One method's answer, as printed in JSON.
#[derive(Clone, Debug, Serialize)]
pub struct MethodResult {
    /// Output-frame mean.
    pub mean: [f64; 3],
    /// Output-frame covariance, row by row.
    pub covariance: [[f64; 3]; 3],
    /// Cost of one point after the per-viewpoint precomputation (µs).
    pub micros: f64,
    /// Cost of the per-viewpoint precomputation (µs).
    pub setup_micros: f64,
}

/// All four methods, keyed by name in a fixed order.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Sigma points of the unscented transform (2n; 2n + 1 for the scaled
    /// set).
    pub sigma_points: usize,
    /// Monte Carlo draws.
    pub samples: usize,
    /// Monte Carlo seed.
    pub seed: u64,
    /// `blind`, `jacobian`, `unscented`, `monte_carlo`.
    pub methods: Methods,
}

/// The four methods (serialised in this order).
#[derive(Clone, Debug, Serialize)]
pub struct Methods {
    /// Measurement covariance only, chain exact.
    pub blind: MethodResult,
    /// First order.
    pub jacobian: MethodResult,
    /// The unscented transform: the paper's 2n sigma points, or the scaled
    /// set (`--alpha`).
    pub unscented: MethodResult,
    /// The reference.
    pub monte_carlo: MethodResult,
}

fn result(g: &Gaussian3, micros: f64, setup_micros: f64) -> MethodResult {
    MethodResult {
        mean: [g.mean.x, g.mean.y, g.mean.z],
        covariance: std::array::from_fn(|i| {
            std::array::from_fn(|j| 0.5 * (g.covariance[(i, j)] + g.covariance[(j, i)]))
        }),
        micros,
        setup_micros,
    }
}

/// Mean time of `f` in µs, repeated for about `budget`.
fn time_micros<T>(budget: Duration, mut f: impl FnMut() -> T) -> f64 {
    let start = Instant::now();
    let mut reps = 0u64;
    while reps == 0 || start.elapsed() < budget {
        black_box(f());
        reps += 1;
    }
    start.elapsed().as_secs_f64() * 1e6 / reps as f64
}

fn run(
    propagator: &dyn Propagator,
    point: &UncertainPoint,
    setup_micros: f64,
    budget: Duration,
) -> MethodResult {
    let g = propagator.propagate(point);
    let micros = time_micros(budget, || propagator.propagate(black_box(point)));
    result(&g, micros, setup_micros)
}

/// Runs the four methods (`samples` Monte Carlo draws from `seed`; the
/// unscented transform with `sigma_set`), timing each for about `budget`
/// (zero: a single run each).
pub fn compare(
    chain: &UncertainChain,
    point: &UncertainPoint,
    sigma_set: SigmaSet,
    samples: usize,
    seed: u64,
    budget: Duration,
) -> Comparison {
    let setup = |f: &mut dyn FnMut()| time_micros(budget / 4, f);
    let blind = BlindPropagator::new(chain);
    let blind_setup = setup(&mut || {
        black_box(BlindPropagator::new(chain));
    });
    let jacobian = JacobianPropagator::new(chain);
    let jacobian_setup = setup(&mut || {
        black_box(JacobianPropagator::new(chain));
    });
    let unscented = UnscentedPropagator::new(chain, sigma_set);
    let unscented_setup = setup(&mut || {
        black_box(UnscentedPropagator::new(chain, sigma_set));
    });
    let mc = MonteCarloPropagator::new(chain, samples, seed);
    let start = Instant::now();
    let mc_result = mc.propagate(point);
    let mc_micros = start.elapsed().as_secs_f64() * 1e6;
    Comparison {
        sigma_points: unscented.points,
        samples: mc.samples,
        seed,
        methods: Methods {
            blind: run(&blind, point, blind_setup, budget),
            jacobian: run(&jacobian, point, jacobian_setup, budget),
            unscented: run(&unscented, point, unscented_setup, budget),
            monte_carlo: result(&mc_result, mc_micros, 0.0),
        },
    }
}

/// One row of the sweep: a method's covariance error against Monte Carlo.
#[derive(Clone, Debug, Serialize)]
pub struct SweepRow {
    /// The rotation standard deviation given to every link (rad).
    pub rotation_sigma: f64,
    /// `blind`, `jacobian` or `unscented`.
    pub method: &'static str,
    /// `‖Γ − Γ_MC‖_F / ‖Γ_MC‖_F`.
    pub relative_frobenius: f64,
    /// `D_KL(MC ‖ method)`.
    pub kl_divergence: f64,
    /// Förstner–Moonen distance to `Γ_MC`.
    pub forstner: f64,
    /// `‖mean − mean_MC‖` (m).
    pub mean_error: f64,
    /// The Monte Carlo relative standard error of a variance, `√(2/(N−1))`.
    pub mc_relative_se: f64,
}

/// `chain` with every link's rotation standard deviation set to `sigma`
/// (translation block kept, rotation–translation correlations dropped).
pub fn with_rotation_sigma(chain: &UncertainChain, sigma: f64) -> UncertainChain {
    let mut out = chain.clone();
    for link in &mut out.links {
        let mut c = Matrix6::zeros();
        c.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&link.pose.covariance.fixed_view::<3, 3>(0, 0));
        for k in 3..6 {
            c[(k, k)] = sigma * sigma;
        }
        link.pose.covariance = c;
    }
    out
}

/// The paper's comparison on one chain: for each rotation sigma, each
/// method's covariance error against a Monte Carlo reference of `samples`
/// draws (the unscented transform with `sigma_set`).
pub fn sweep(
    chain: &UncertainChain,
    point: &UncertainPoint,
    sigma_set: SigmaSet,
    sigmas: &[f64],
    samples: usize,
    seed: u64,
) -> Vec<SweepRow> {
    let mut rows = Vec::new();
    for &sigma in sigmas {
        let chain = with_rotation_sigma(chain, sigma);
        let mc = MonteCarloPropagator::new(&chain, samples, seed).propagate(point);
        let methods: [(&'static str, Gaussian3); 3] = [
            ("blind", BlindPropagator::new(&chain).propagate(point)),
            ("jacobian", JacobianPropagator::new(&chain).propagate(point)),
            (
                "unscented",
                UnscentedPropagator::new(&chain, sigma_set).propagate(point),
            ),
        ];
        for (method, g) in methods {
            rows.push(SweepRow {
                rotation_sigma: sigma,
                method,
                relative_frobenius: relative_frobenius(&g.covariance, &mc.covariance),
                kl_divergence: kl_divergence(&mc.mean, &mc.covariance, &g.mean, &g.covariance),
                forstner: forstner_distance(&g.covariance, &mc.covariance),
                mean_error: (g.mean - mc.mean).norm(),
                mc_relative_se: (2.0 / (samples as f64 - 1.0)).sqrt(),
            });
        }
    }
    rows
}

/// `count` log-spaced values from `lo` to `hi`.
pub fn log_space(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    (0..count)
        .map(|i| lo * (hi / lo).powf(i as f64 / (count.max(2) - 1) as f64))
        .collect()
}
