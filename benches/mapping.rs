//! Map insertion: the same scans (the quickstart run) inserted with the OPDF
//! merge (unscented, jacobian, blind) and with the OctoMap-style ray update,
//! at 2 cm, one core. Printed: beams/s, each method's ratio to the ray update
//! measured in the same run, and bytes per leaf beside OctoMap's layout
//! (16 bytes per node + 64 per inner node); then one map built on two
//! cores against one (same tree asserted). The side-by-side run against
//! OctoMap itself is `bash benches/octomap/compare.sh`.

use criterion::{criterion_group, criterion_main, Criterion};
use sigmap::experiment::model::{build_map, MapperView, Method};
use sigmap::experiment::{simulate, Experiment};
use sigmap::geometry::Vector3;
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

const RESOLUTION: f64 = 0.02;

fn bench(c: &mut Criterion) {
    let experiment = Experiment::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/quickstart.toml"
    )))
    .expect("quickstart");
    let run = simulate(&experiment, 1, |_| {}).expect("simulate");
    let view = MapperView::of(&experiment);
    let beams: usize = run.scans.iter().map(|s| s.measurements.len()).sum();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut group = c.benchmark_group("insert_quickstart_2cm");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(4))
        .warm_up_time(Duration::from_millis(500));
    for method in [Method::RayUpdate, Method::Unscented] {
        group.bench_function(method.as_str(), |b| {
            b.iter(|| {
                pool.install(|| {
                    black_box(
                        build_map(&view, &run.scans, method, RESOLUTION, &Vector3::zeros())
                            .expect("the quickstart maps"),
                    )
                })
            })
        });
    }
    group.finish();

    let build = |pool: &rayon::ThreadPool, method| {
        pool.install(|| {
            build_map(&view, &run.scans, method, RESOLUTION, &Vector3::zeros())
                .expect("the quickstart maps")
        })
    };
    let seconds_on = |pool: &rayon::ThreadPool, method| {
        let start = Instant::now();
        let mut reps = 0;
        while reps < 3 || start.elapsed() < Duration::from_secs(1) {
            black_box(build(pool, method));
            reps += 1;
        }
        start.elapsed().as_secs_f64() / reps as f64
    };
    let seconds = |method| seconds_on(&pool, method);
    let baseline = seconds(Method::RayUpdate);
    println!("\ninsertion of {beams} beams at {RESOLUTION} m, one core (ratio: beams/s against the ray update):");
    for method in Method::ALL {
        let s = if method == Method::RayUpdate {
            baseline
        } else {
            seconds(method)
        };
        let stats = build_map(&view, &run.scans, method, RESOLUTION, &Vector3::zeros())
            .expect("the quickstart maps")
            .stats();
        println!(
            "  {:<11} {:6.3} M beams/s  {:5.2}x   {:5.1} bytes/leaf (OctoMap's layout: {:5.1})",
            method.as_str(),
            beams as f64 / s / 1e6,
            baseline / s,
            stats.bytes as f64 / stats.leaves as f64,
            (16 * stats.nodes + 64 * stats.inner) as f64 / stats.leaves as f64
        );
    }

    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    println!("\none map on two cores (ratio: time on one core / time on two):");
    for method in [Method::RayUpdate, Method::Unscented] {
        assert!(
            build(&pool, method) == build(&two, method),
            "{method:?}: two cores built a different tree"
        );
        let (one_core, two_cores) = (seconds_on(&pool, method), seconds_on(&two, method));
        println!(
            "  {:<11} {:6.3} s on one core, {:6.3} s on two: {:5.2}x",
            method.as_str(),
            one_core,
            two_cores,
            one_core / two_cores
        );
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
