//! One map built on one thread and on several: the same tree, value for
//! value (the merge's parallel search and the ray update's parallel walk
//! must not depend on how the work was split or which thread came first;
//! nor must the beam pooling's parallel windows, nor the surface samples).

use sigmap::experiment::{simulate, Experiment, Overrides};
use sigmap::geometry::Vector3;
use sigmap::mapping::pooling::Pooling;
use sigmap::mapping::{build_map, Method};
use std::path::Path;

#[test]
fn a_map_is_the_same_on_one_thread_and_on_three() {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/quickstart.toml"
    ));
    let experiment = Experiment::load(path).expect("quickstart");
    let run = simulate(&experiment, 1, |_| {}).expect("simulate");
    let pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
    };
    let (one, three) = (pool(1), pool(3));
    // 1 cm: tasks of 16³ cells; 5 cm: of 2³; the pooled map at 2 cm.
    // The last: surface samples between beams (interpolate_beams).
    let cases = [
        (Pooling::Off, 0.01, Method::RayUpdate, false),
        (Pooling::Off, 0.01, Method::Unscented, false),
        (Pooling::Off, 0.01, Method::Correlated, false),
        (Pooling::Off, 0.05, Method::RayUpdate, false),
        (Pooling::Off, 0.05, Method::Unscented, false),
        (Pooling::Off, 0.05, Method::Correlated, false),
        (Pooling::Windows, 0.02, Method::Unscented, false),
        (Pooling::Faces, 0.02, Method::Unscented, false),
        (Pooling::Windows, 0.01, Method::Unscented, true),
    ];
    for (pooling, resolution, method, samples) in cases {
        let overrides = Overrides {
            beam_pooling: Some(pooling),
            interpolate_beams: Some(samples),
            ..Overrides::default()
        };
        let experiment = Experiment::load_with(path, &[], &overrides).expect("quickstart");
        let view = experiment.mapper_view();
        let build = |pool: &rayon::ThreadPool| {
            pool.install(|| {
                build_map(&view, &run.scans, method, resolution, &Vector3::zeros())
                    .expect("the quickstart maps")
            })
        };
        let (a, b) = (build(&one), build(&three));
        let (la, lb) = (a.leaves(), b.leaves());
        assert!(
            la.len() > 1000,
            "{method:?} at {resolution}: {} leaves",
            la.len()
        );
        let differ = la.iter().zip(&lb).filter(|(x, y)| x != y).count();
        assert!(
            la.len() == lb.len() && differ == 0,
            "{method:?} at {resolution} m ({pooling:?}): {} vs {} leaves, {differ} differ",
            la.len(),
            lb.len()
        );
    }
}
