use super::*;
use crate::experiment::run::consensus_truth::hits_placed_by_the_nominal_chain;
use crate::mapping::octree::DEPTH;
use crate::mapping::pooling::Pooling;
use crate::mapping::scan::BeamStatus;
use std::path::Path;

/// The quickstart with only a scene-registration error (T_sw), large:
/// arm and hand-eye exact.
fn registration_only(dir: &Path) -> Experiment {
    quickstart_with_profile(
        dir,
        "[range]\nsigma0 = 0.001\nk = 0.0\nangular_sigma = 0.0\ndropout = 0.0\n\
         [world_from_scene]\nsigma = [0.004, 0.004, 0.004, 0.02, 0.02, 0.02]\n",
        "",
    )
}

#[test]
fn a_runs_truth_is_the_workspace_truth_on_every_observable_cell() {
    // The truth computed around the observable mask holds every
    // observable cell the workspace truth holds, with its value, and
    // nothing far outside the mask.
    // The tabletop in a 6 m x 6 m x 2.5 m workspace: the rays (2 m)
    // see only part of it.
    let dir = tempfile::tempdir().unwrap();
    registration_only(dir.path());
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = std::fs::read_to_string(root.join("scenes/tabletop.toml"))
        .unwrap()
        .replace("meshes/", &format!("{}/scenes/meshes/", root.display()))
        .replace("min = [-0.4, -0.4, -0.04]", "min = [-3.0, -3.0, -0.04]")
        .replace("max = [0.4, 0.4, 0.36]", "max = [3.0, 3.0, 2.5]");
    std::fs::write(dir.path().join("wide.toml"), scene).unwrap();
    let file = dir.path().join("experiment.toml");
    let text = std::fs::read_to_string(&file).unwrap().replace(
        &format!("{}/scenes/tabletop.toml", root.display()),
        &dir.path().join("wide.toml").display().to_string(),
    );
    std::fs::write(&file, text).unwrap();
    let experiment = Experiment::load(&file).unwrap();
    for seed in [1, 4] {
        let run = simulate(&experiment, seed, |_| {}).unwrap();
        let offset = experiment.map_offset(seed);
        let seen = observable(&experiment, &run.truth.scans, &offset);
        let (around, whole) = (
            run_truth(&experiment, seed, &KeyBox::spanning(seen.iter().copied())),
            ground_truth(&experiment, seed),
        );
        let mut known = 0;
        for &code in &seen {
            let key = crate::mapping::Key::from_morton(code);
            let value = |t: &Octree| t.value_at(&t.center(&key, DEPTH));
            assert_eq!(value(&around), value(&whole), "{key:?}");
            known += usize::from(value(&whole).is_some());
        }
        assert!(known > 10_000, "{known}");
        assert!(
            around.stats().leaves * 2 < whole.stats().leaves,
            "{:?} {:?}",
            around.stats(),
            whole.stats()
        );
        let span = KeyBox::spanning(seen.iter().copied());
        around.visit_leaves(|leaf| assert!(span.holds(&leaf.key, leaf.depth), "{leaf:?}"));
    }
}

#[test]
fn the_registered_truth_holds_the_surface_where_the_nominal_chain_puts_it() {
    // With only T_sw wrong, a true hit seen through the nominal chain lies
    // at T̂_sw⁻¹ T_sw x: on the registered truth's surface, off the truth's.
    let dir = tempfile::tempdir().unwrap();
    let experiment = registration_only(dir.path());
    let seed = 3;
    let run = simulate(&experiment, seed, |_| {}).unwrap();
    let offset = experiment.map_offset(seed);
    let registered = registered_truth(&experiment, &run.truth, 0.01, &offset, &KeyBox::ALL);
    let truth = ground_truth(&experiment, seed);
    let (hits, in_registered, in_truth) =
        hits_placed_by_the_nominal_chain(&experiment, &run, &offset, (&registered, &truth));
    assert!(hits > 10_000, "{hits} hits");
    assert_eq!(in_registered, hits, "every hit on the registered surface");
    assert!(
        (in_truth as f64) < 0.8 * hits as f64,
        "the error moves hits off the truth: {in_truth} of {hits}"
    );
}

#[test]
fn without_a_registration_error_the_registered_truth_is_the_truth() {
    let mut experiment = Experiment::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/quickstart.toml"
    )))
    .unwrap();
    experiment.profile_mut().scale_pose_errors(0.0);
    let run = simulate(&experiment, 1, |_| {}).unwrap();
    let offset = experiment.map_offset(1);
    let registered = registered_truth(&experiment, &run.truth, 0.01, &offset, &KeyBox::ALL);
    assert_eq!(registered.leaves(), ground_truth(&experiment, 1).leaves());
}

/// A frame's scale error is shared by its beams, so pooling them
/// averages their own noise and not the scale: with a 2% scale error
/// (12 mm at 0.6 m) against 1 mm of own noise and the chain exact,
/// the NEES of the pooled hits, averaged per frame, has mean 3 over
/// 72 frames. A frame's mean is about `z² + 2` (`z` its scale's
/// standardised draw), of variance 2: the bound is 5 standard errors.
/// Pooling's own σ alone (a few tenths of a millimetre) puts it in the
/// thousands.
#[test]
fn the_nees_of_pooled_hits_holds_the_frames_scale_error() {
    let dir = tempfile::tempdir().unwrap();
    let experiment = quickstart_with_profile(
        dir.path(),
        "[range]\nsigma0 = 0.001\nangular_sigma = 0.0005\nscale_sigma = 0.02\n",
        "",
    );
    let view = experiment.mapper_view();
    assert_eq!(view.settings.beam_pooling, Pooling::Windows);
    let directions = experiment.scanner().directions();
    let mut frames = Vec::new();
    for seed in 1..=12 {
        let run = simulate(&experiment, seed, |_| {}).unwrap();
        for (scan, truth) in run.scans.iter().zip(&run.truth.scans) {
            // The truth records the scale the frame was measured with.
            let mut ratios: Vec<f64> = (scan.measurements.iter().zip(&truth.beams))
                .filter(|(m, _)| m.status == BeamStatus::Hit)
                .map(|(m, t)| m.range / t.range)
                .collect();
            ratios.sort_by(f64::total_cmp);
            let median = ratios[ratios.len() / 2];
            assert!((median - truth.range_scale).abs() < 1e-3);
            let ranges = measured_ranges(&view, &experiment.scanner().layout, scan).unwrap();
            let pooled = ranges.iter().flatten().filter(|p| p.normal.is_some());
            assert!(pooled.count() > 1000);
            let chain = scan_chain(scan);
            let unscented = propagator(Method::Unscented, &chain, view.sigma_set).unwrap();
            let pairs = errors_against_truth(&view.range, directions, truth, &ranges, &*unscented);
            let sum: f64 = pairs.iter().map(|(e, c)| nees(e, c)).sum();
            frames.push(sum / pairs.len() as f64);
        }
    }
    let n = frames.len() as f64;
    let anees = frames.iter().sum::<f64>() / n;
    assert!(
        (anees - 3.0).abs() < 5.0 * (2.0 / n).sqrt(),
        "ANEES {anees} over {n} frames"
    );
}

#[test]
fn the_nees_checks_pooled_hits_with_the_slide() {
    // The NEES compares the true hit with the hit's covariance, whose
    // spread along the beam holds the slide of a turned beam on a
    // slanted plane; the maps draw the plane's prediction σ alone.
    let mut experiment = Experiment::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/quickstart.toml"
    )))
    .unwrap();
    experiment
        .map_mut()
        .pool_every_method(crate::mapping::pooling::Pooling::Windows);
    let run = simulate(&experiment, 1, |_| {}).unwrap();
    let view = experiment.mapper_view();
    let (scan, truth) = (&run.scans[0], &run.truth.scans[0]);
    let ranges = measured_ranges(&view, &experiment.scanner().layout, scan).unwrap();
    let chain = scan_chain(scan);
    let blind = propagator(Method::Blind, &chain, view.sigma_set).unwrap();
    let directions = experiment.scanner().directions();
    let pairs = errors_against_truth(&view.range, directions, truth, &ranges, blind.as_ref());
    let hits: Vec<_> = ranges
        .iter()
        .zip(directions)
        .filter_map(|(p, d)| p.map(|p| (p, d)))
        .collect();
    assert_eq!(pairs.len(), hits.len());
    let rotation = chain.nominal().rotation;
    let (mut pooled, mut wider) = (0, 0);
    for ((p, d), (_, covariance)) in hits.iter().zip(&pairs) {
        let v = rotation * *d;
        let along = (v.transpose() * covariance * v)[(0, 0)];
        assert!(along >= p.sigma * p.sigma * (1.0 - 1e-9));
        if p.normal.is_some() {
            pooled += 1;
            wider += usize::from(along > 1.21 * p.sigma * p.sigma);
        }
    }
    assert!(pooled > 1000, "{pooled} pooled hits");
    assert!(wider * 10 > pooled, "{wider} of {pooled} with the slide");
}
