//! Ray-casting throughput of the simulator on the tabletop scene.
//!
//! Baseline (same run): the scene's BVH ray cast, one ray after another on one
//! core. Measured against it: the full simulator (`cast_beams`: jitter, noise,
//! dropout, truth) spread over every core by rayon. The target is at
//! least 3.5 M rays/s on 2 cores. Run with `cargo bench --bench raycast`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use sigmap::experiment::Experiment;
use sigmap::geometry::{Point3, Vector3};
use sigmap::sim::scan::cast_beams;
use sigmap::sim::streams::Streams;
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

fn load() -> Experiment {
    Experiment::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/quickstart.toml"
    )))
    .expect("quickstart experiment")
}

fn rays(experiment: &Experiment) -> Vec<(Point3, Vector3)> {
    experiment
        .viewpoints()
        .iter()
        .flat_map(|v| {
            let pose = experiment.nominal_scene_from_camera(&v.joints);
            let origin = Point3::from(pose.translation.vector);
            experiment
                .scanner()
                .directions()
                .iter()
                .map(move |d| (origin, pose.rotation * d))
        })
        .collect()
}

fn sequential(experiment: &Experiment, rays: &[(Point3, Vector3)]) -> usize {
    let max = experiment.scanner().max_range;
    rays.iter()
        .filter(|(o, d)| experiment.scene().cast_ray(o, d, max).is_some())
        .count()
}

fn simulator(experiment: &Experiment, streams: &Streams) -> usize {
    experiment
        .viewpoints()
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let pose = experiment.nominal_scene_from_camera(&v.joints);
            let (m, _) = cast_beams(
                experiment.scene(),
                experiment.scanner(),
                &experiment.profile().range,
                &pose,
                streams,
                i as u32,
            );
            m.len()
        })
        .sum()
}

/// Rays per second of `f` over about a second.
fn rate(n: usize, mut f: impl FnMut() -> usize) -> f64 {
    let start = Instant::now();
    let mut done = 0;
    while start.elapsed() < Duration::from_secs(1) {
        black_box(f());
        done += n;
    }
    done as f64 / start.elapsed().as_secs_f64()
}

fn bench(c: &mut Criterion) {
    let experiment = load();
    let rays = rays(&experiment);
    let streams = Streams::new(1);
    let mut group = c.benchmark_group("raycast_tabletop");
    group.throughput(Throughput::Elements(rays.len() as u64));
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(4));
    group.bench_function("bvh_sequential_1_core", |b| {
        b.iter(|| black_box(sequential(&experiment, &rays)));
    });
    group.bench_function("simulator_rayon_all_cores", |b| {
        b.iter(|| black_box(simulator(&experiment, &streams)));
    });
    group.finish();

    let baseline = rate(rays.len(), || sequential(&experiment, &rays));
    let simulated = rate(rays.len(), || simulator(&experiment, &streams));
    let threads = rayon::current_num_threads();
    println!(
        "\nraycast on '{}' ({} triangles, {} rays/pass):\n  baseline, BVH cast on 1 core:      {:6.2} M rays/s\n  \
         simulator on {threads} threads:           {:6.2} M rays/s  (ratio {:.2}x; target >= 3.5 M rays/s on 2 cores: {})",
        experiment.scene().name,
        experiment.scene().triangle_count(),
        rays.len(),
        baseline / 1e6,
        simulated / 1e6,
        simulated / baseline,
        if simulated >= 3.5e6 { "met" } else { "NOT met" }
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
