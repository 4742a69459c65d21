//! Per-point cost of each propagator on the paper's 3-link chain, with and
//! without the per-viewpoint precomputation, and a 100 000-beam scan.
//!
//! Printed ratios are against the precomputed Jacobian measured in the same
//! run. The target: the precomputed unscented propagation of a
//! 100 000-beam scan under 20 ms on one core. Run `cargo bench --bench propagate`.

use criterion::{criterion_group, criterion_main, Criterion};
use sigmap::geometry::{Matrix3, Pose, Vector3};
use sigmap::uncertainty::jacobian::jacobian_naive;
use sigmap::uncertainty::unscented::unscented_naive;
use sigmap::uncertainty::{
    BlindPropagator, Gaussian3, JacobianPropagator, Propagator, SigmaSet, UncertainChain,
    UncertainPoint, UncertainPose, UnscentedPropagator,
};
use std::hint::black_box;
use std::time::{Duration, Instant};

fn pose(xyz: [f64; 3], rpy: [f64; 3], st: f64, sa: f64) -> UncertainPose {
    UncertainPose::from_sigmas(Pose::new(xyz, rpy), [st, st, st, sa, sa, sa])
}

fn chain() -> UncertainChain {
    UncertainChain::paper(
        pose([0.1, 0.0, 0.2], [0.0, 0.0, 0.3], 0.001, 0.002),
        pose([0.6, 0.1, 0.5], [3.0, 0.2, -1.1], 0.0005, 0.003),
        pose([0.0, 0.07, 0.045], [0.0, 0.0, -1.57], 0.001, 0.002),
    )
}

/// A 100 000-beam scan: a 400 x 250 raster of points 0.5-1.5 m away.
fn scan() -> Vec<UncertainPoint> {
    (0..100_000)
        .map(|i| {
            let (u, v) = (
                (i % 400) as f64 / 400.0 - 0.5,
                (i / 400) as f64 / 250.0 - 0.5,
            );
            let d = Vector3::new(u, v, 1.0).normalize();
            let r = 0.5 + (i % 97) as f64 / 97.0;
            UncertainPoint {
                mean: d * r,
                covariance: d * d.transpose() * (0.001 + 0.002 * r).powi(2)
                    + (Matrix3::identity() - d * d.transpose()) * (r * 5e-4).powi(2),
            }
        })
        .collect()
}

/// Seconds per call of `f`, over about half a second.
fn seconds(mut f: impl FnMut()) -> f64 {
    let start = Instant::now();
    let mut reps = 0u32;
    while reps < 3 || start.elapsed() < Duration::from_millis(500) {
        f();
        reps += 1;
    }
    start.elapsed().as_secs_f64() / reps as f64
}

fn bench(c: &mut Criterion) {
    let chain = chain();
    let point = UncertainPoint {
        mean: Vector3::new(0.0, 0.1, 1.2),
        covariance: Matrix3::identity() * 2.5e-7,
    };
    let blind = BlindPropagator::new(&chain);
    let jacobian = JacobianPropagator::new(&chain);
    let unscented = UnscentedPropagator::new(&chain, SigmaSet::Paper);
    let mut group = c.benchmark_group("propagate_point");
    group
        .sample_size(30)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(500));
    group.bench_function("blind", |b| b.iter(|| blind.propagate(black_box(&point))));
    group.bench_function("jacobian_precomputed", |b| {
        b.iter(|| jacobian.propagate(black_box(&point)));
    });
    group.bench_function("jacobian_naive", |b| {
        b.iter(|| jacobian_naive(&chain, black_box(&point)));
    });
    group.bench_function("unscented_precomputed", |b| {
        b.iter(|| unscented.propagate(black_box(&point)));
    });
    group.bench_function("unscented_naive", |b| {
        b.iter(|| unscented_naive(&chain, black_box(&point), SigmaSet::Paper));
    });
    group.finish();

    let points = scan();
    let mut out = vec![Gaussian3::default(); points.len()];
    let per_point = |p: &dyn Propagator, out: &mut [Gaussian3]| {
        seconds(|| p.propagate_into(black_box(&points), out)) / points.len() as f64
    };
    let jac = per_point(&jacobian, &mut out);
    let ut = per_point(&unscented, &mut out);
    let bl = per_point(&blind, &mut out);
    let jac_naive = seconds(|| {
        black_box(jacobian_naive(&chain, black_box(&point)));
    });
    let ut_naive = seconds(|| {
        black_box(unscented_naive(&chain, black_box(&point), SigmaSet::Paper));
    });
    let scan_ms = seconds(|| {
        let p = UnscentedPropagator::new(&chain, SigmaSet::Paper);
        p.propagate_into(black_box(&points), &mut out);
    }) * 1e3;
    println!("\nper point, 3-link chain, one core (ratio to the precomputed Jacobian):");
    for (name, s) in [
        ("blind", bl),
        ("jacobian, precomputed", jac),
        ("jacobian, naive 3x21 J Γ Jᵀ", jac_naive),
        ("unscented, precomputed (42 pts)", ut),
        ("unscented, naive (42 chain evaluations)", ut_naive),
    ] {
        println!("  {name:<42} {:8.1} ns  {:6.2}x", s * 1e9, s / jac);
    }
    println!(
        "  unscented/jacobian, both precomputed: {:.2}x; both naive: {:.2}x",
        ut / jac,
        ut_naive / jac_naive
    );
    println!(
        "100 000-beam scan, precomputed unscented incl. setup, one core: {scan_ms:.2} ms (target < 20 ms: {})",
        if scan_ms < 20.0 { "met" } else { "NOT met" }
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
