//! Are the propagated covariances honest against the simulator's truth?
//!
//! 200 independent runs of the quickstart's first viewpoint (each run draws its
//! own T_sw, T_cr, T_rw and beam errors); from each, one measured point (the
//! hit nearest the centre of the raster) is propagated into the scene frame
//! and compared with the true surface point. One point per run keeps the
//! errors independent (docs/math.md §6.6), so N·ANEES ~ χ²(3N): the Jacobian and
//! unscented ANEES must fall in the two-sided 95% band for N = 200
//! ([2.670, 3.349]); blind, which ignores the pose errors, must fall far
//! above it (over-confident).

mod common;

use sigmap::experiment::{simulate, Experiment};
use sigmap::mapping::scan::BeamStatus;
use sigmap::uncertainty::consistency::ConsistencyReport;
use sigmap::uncertainty::{
    BlindPropagator, Gaussian3, JacobianPropagator, Propagator, SigmaSet, UncertainChain,
    UncertainPoint, UnscentedPropagator,
};

#[test]
fn propagated_covariances_are_consistent_with_the_simulated_truth() {
    // The quickstart with its first viewpoint only.
    let text = common::portable_quickstart();
    let second = text.match_indices("[[viewpoint]]").nth(1).unwrap().0;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("one_viewpoint.toml");
    std::fs::write(&path, &text[..second]).unwrap();
    let experiment = Experiment::load(&path).unwrap();
    assert_eq!(experiment.viewpoints().len(), 1);
    let centre = experiment.scanner().directions().len() / 2;
    let runs = 200;
    let mut errors: [Vec<(nalgebra::Vector3<f64>, Gaussian3)>; 3] = Default::default();
    for seed in 0..runs {
        let run = simulate(&experiment, 1000 + seed, |_| {}).unwrap();
        let scan = &run.scans[0];
        let beam = (centre..scan.measurements.len())
            .find(|&i| scan.measurements[i].status == BeamStatus::Hit)
            .unwrap();
        let d = experiment.scanner().directions()[beam];
        let r = scan.measurements[beam].range;
        let point = UncertainPoint {
            mean: d * r,
            covariance: experiment.profile().range.point_covariance(&d, r),
        };
        let chain = UncertainChain::paper(
            scan.chain.world_from_scene,
            scan.chain.world_from_robot,
            scan.chain.robot_from_camera,
        );
        let truth = run.truth.scans[0].beams[beam].point.coords;
        let methods: [Box<dyn Propagator>; 3] = [
            Box::new(BlindPropagator::new(&chain)),
            Box::new(JacobianPropagator::new(&chain)),
            Box::new(UnscentedPropagator::new(&chain, SigmaSet::Paper)),
        ];
        for (k, m) in methods.iter().enumerate() {
            let g = m.propagate(&point);
            errors[k].push((truth - g.mean, g));
        }
    }
    let report =
        |k: usize| ConsistencyReport::new(errors[k].iter().map(|(e, g)| (*e, &g.covariance)));
    let (blind, jacobian, unscented) = (report(0), report(1), report(2));
    for (name, r) in [
        ("blind", &blind),
        ("jacobian", &jacobian),
        ("unscented", &unscented),
    ] {
        eprintln!("{name:<10} ANEES {:8.3} (95% band {:.3}-{:.3}), coverage 1/2/3 sigma {:.3} {:.3} {:.3}", r.anees, r.bounds.0, r.bounds.1, r.coverage[0], r.coverage[1], r.coverage[2]);
    }
    assert!((jacobian.bounds.0 - 2.670).abs() < 1e-3 && (jacobian.bounds.1 - 3.349).abs() < 1e-3);
    for (name, r) in [("jacobian", &jacobian), ("unscented", &unscented)] {
        assert!(
            r.is_consistent(),
            "{name}: ANEES {} outside {:?}",
            r.anees,
            r.bounds
        );
        // Coverage of the 2-sigma ellipsoid: 73.9% ± 5 binomial SE (3.1% at N = 200).
        assert!(
            (r.coverage[1] - r.expected[1]).abs() < 5.0 * (0.739f64 * 0.261 / runs as f64).sqrt(),
            "{name}: {:?}",
            r.coverage
        );
    }
    assert!(
        blind.anees > 10.0 * blind.bounds.1,
        "blind ANEES {}",
        blind.anees
    );
}
