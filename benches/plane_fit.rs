//! The 3 × 3 symmetric eigen-decomposition of beam pooling's plane fits
//! (docs/math.md §5.5; two per beam with sigmap's defaults): sigmap's closed
//! form (`geometry::symmetric_eigen`) against nalgebra's general solver, on
//! the noise-corrected scatter matrices of 3 × 3 windows of hits on tilted
//! planes, measured in the same run. Printed: ns per decomposition and the
//! ratio. Run `cargo bench --bench plane_fit`.

use criterion::{criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sigmap::geometry::{symmetric_eigen, Matrix3, Vector3};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// Scatter matrices of 3 × 3 windows of hits 0.5–1.5 m away on planes
/// tilted up to 70° (beams 0.25° apart, range noise 1 mm + 2 mm/m), less
/// their noise's share, as `pooling::fit_plane` builds them.
fn windows(count: usize) -> Vec<Matrix3> {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let step = 0.25f64.to_radians();
    (0..count)
        .map(|_| {
            let r0 = rng.random_range(0.5..1.5);
            let tilt = rng.random_range(0.0..70f64.to_radians());
            let normal = Vector3::new(tilt.sin(), 0.0, -tilt.cos());
            let sigma = 0.001 + 0.002 * r0;
            let (mut points, mut noise) = (Vec::with_capacity(9), Matrix3::zeros());
            for i in 0..9 {
                let (u, v) = ((i % 3) as f64 - 1.0, (i / 3) as f64 - 1.0);
                let d = Vector3::new(u * step, v * step, 1.0).normalize();
                // The plane through (0, 0, r0) with `normal`, met along d.
                let r = r0 * normal.z / normal.dot(&d);
                let r = r + sigma * rng.random_range(-1.0..1.0);
                points.push(d * r);
                noise += d * d.transpose() * (sigma * sigma);
            }
            let centroid = points.iter().sum::<Vector3>() / 9.0;
            points.iter().fold(Matrix3::zeros(), |a, p| {
                let o = p - centroid;
                a + o * o.transpose()
            }) - noise * (8.0 / 9.0)
        })
        .collect()
}

fn per_call(matrices: &[Matrix3], f: impl Fn(&Matrix3) -> f64) -> f64 {
    let rounds = 20;
    let start = Instant::now();
    for _ in 0..rounds {
        for m in matrices {
            black_box(f(black_box(m)));
        }
    }
    start.elapsed().as_secs_f64() / (rounds * matrices.len()) as f64
}

fn bench(c: &mut Criterion) {
    let matrices = windows(10_000);
    let ours = |m: &Matrix3| symmetric_eigen(m).0.min();
    let nalgebra = |m: &Matrix3| m.symmetric_eigen().eigenvalues.min();
    let mut group = c.benchmark_group("plane_fit_eigen");
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(300));
    group.bench_function("closed_form", |b| b.iter(|| ours(black_box(&matrices[7]))));
    group.bench_function("nalgebra", |b| b.iter(|| nalgebra(black_box(&matrices[7]))));
    group.finish();
    // Alternating rounds over all the windows, the same run.
    let mut ratios = Vec::new();
    let (mut t_ours, mut t_nalgebra) = (0.0, 0.0);
    for _ in 0..5 {
        let (a, b) = (per_call(&matrices, ours), per_call(&matrices, nalgebra));
        ratios.push(b / a);
        (t_ours, t_nalgebra) = (t_ours + a / 5.0, t_nalgebra + b / 5.0);
    }
    ratios.sort_by(f64::total_cmp);
    println!(
        "\nplane-fit eigen-decomposition, one core: closed form {:.0} ns, nalgebra {:.0} ns; \
         nalgebra / closed form median {:.2}x ({:.2}-{:.2} over 5 rounds)",
        t_ours * 1e9,
        t_nalgebra * 1e9,
        ratios[2],
        ratios[0],
        ratios[4]
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
