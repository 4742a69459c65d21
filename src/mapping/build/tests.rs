use super::*;
use crate::experiment::shipped_quickstart as quickstart;
use crate::experiment::Experiment;
use crate::geometry::Matrix6;
use crate::geometry::Pose;
use crate::mapping::measured::*;
use crate::mapping::method::*;
use crate::mapping::octree::{Key, DEPTH};
use crate::mapping::scan::*;
use crate::uncertainty::SigmaSet;
use crate::uncertainty::UncertainPose;

#[test]
fn the_chain_splits_into_shared_and_per_viewpoint_links() {
    let pose =
        |s: f64| UncertainPose::from_sigmas(Pose::new([0.1, 0.2, 0.3], [0.1, 0.2, 0.3]), [s; 6]);
    let chain = UncertainChain::paper(pose(0.01), pose(0.02), pose(0.03));
    let shared = split_chain(&chain, true);
    let own = split_chain(&chain, false);
    for i in 0..3 {
        assert_eq!(
            shared.links[i].pose.covariance + own.links[i].pose.covariance,
            chain.links[i].pose.covariance
        );
        assert_eq!(shared.links[i].pose.mean, chain.links[i].pose.mean);
    }
    // T_sw and T_cr are shared; T_rw is the viewpoint's own.
    assert!(shared.links[0].pose.covariance[(0, 0)] > 0.0);
    assert!(shared.links[1].pose.is_exact());
    assert!(shared.links[2].pose.covariance[(0, 0)] > 0.0);
    assert!(own.links[1].pose.covariance[(0, 0)] > 0.0);
}

#[test]
fn a_whole_cell_offset_shifts_the_map_by_that_cell() {
    // The map frame is `scene + offset` for origins and hits alike: a
    // whole-cell offset moves every cell's value to the cell that many
    // keys away, up to the rounding of a point near a cell face.
    let experiment = quickstart();
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let view = experiment.mapper_view();
    let resolution = 0.02;
    let shift = [3i32, -2, 1];
    let offset = Vector3::from(shift.map(|s| f64::from(s) * resolution));
    for method in [Method::Unscented, Method::RayUpdate] {
        let map =
            |offset: &Vector3| build_map(&view, &run.scans, method, resolution, offset).unwrap();
        let (still, moved) = (map(&Vector3::zeros()), map(&offset));
        let leaves = still.leaves();
        let differ = leaves
            .iter()
            .filter(|leaf| {
                let key = Key(std::array::from_fn(|a| {
                    (i32::from(leaf.key.0[a]) + shift[a]) as u16
                }));
                let there = moved.query(&key, DEPTH);
                there.is_none_or(|v| (v - leaf.value).abs() > 0.05)
            })
            .count();
        assert!(
            differ * 500 < leaves.len(),
            "{method}: {differ} of {} leaves moved elsewhere",
            leaves.len()
        );
    }
}

#[test]
fn a_map_is_the_same_file_whatever_the_thread_count() {
    // Scans are prepared on every thread and applied in order
    // (mapping::pipeline): one, two and three threads, the same bytes.
    let experiment = quickstart();
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let view = experiment.mapper_view();
    let clamp = view.settings.update.clamp;
    for method in [Method::Unscented, Method::Correlated, Method::RayUpdate] {
        let file = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let tree = pool
                .install(|| build_map(&view, &run.scans, method, 0.05, &Vector3::zeros()).unwrap());
            crate::mapping::octomap_io::to_bt(&tree, clamp)
        };
        let one = file(1);
        assert!(one.len() > 1000, "{method}: {} bytes", one.len());
        for threads in [2, 3] {
            assert!(file(threads) == one, "{method}: {threads} threads");
        }
    }
}

#[test]
fn without_shared_error_the_correlated_map_is_the_unscented_map() {
    let mut experiment = quickstart();
    let offset = Vector3::zeros();
    let maps = |experiment: &Experiment| {
        let run = crate::experiment::simulate(experiment, 1, |_| {}).unwrap();
        let view = experiment.mapper_view();
        let map = |m| build_map(&view, &run.scans, m, 0.02, &offset).unwrap();
        (map(Method::Unscented), map(Method::Correlated))
    };
    let (unscented, correlated) = maps(&experiment);
    assert_ne!(
        unscented, correlated,
        "the shared error is accounted differently"
    );
    experiment.profile_mut().world_from_scene = Matrix6::zeros();
    experiment.profile_mut().robot_from_camera = Matrix6::zeros();
    let (unscented, correlated) = maps(&experiment);
    assert_eq!(unscented, correlated);
}

#[test]
fn the_shared_error_is_taken_once_on_the_fused_map() {
    // The same scans, believed with and without shared covariance: the
    // viewpoints fuse identically (arm error only), so the maps differ
    // only by the shared-motion step, which must have run.
    let experiment = quickstart();
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let mut believed_exact = run.scans.clone();
    for scan in &mut believed_exact {
        scan.chain.world_from_scene.covariance = Matrix6::zeros();
        scan.chain.robot_from_camera.covariance = Matrix6::zeros();
    }
    let offset = Vector3::zeros();
    let view = experiment.mapper_view();
    let map = |scans: &[Scan]| build_map(&view, scans, Method::Correlated, 0.02, &offset).unwrap();
    let (with_shared, without) = (map(&run.scans), map(&believed_exact));
    assert_ne!(with_shared, without, "the shared-motion step ran");
}

#[test]
fn pooling_narrows_most_hits_and_only_when_asked() {
    let mut experiment = quickstart();
    // The quickstart leaves pooling to the default, windows (§5.7).
    assert_eq!(experiment.map().beam_pooling, Pooling::Windows);
    experiment.map_mut().pool_every_method(Pooling::Off);
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let scan = &run.scans[0];
    let along = |e: &Experiment| -> Vec<(f64, f64)> {
        let view = e.mapper_view();
        measured_ranges(&view, &e.scanner().layout, scan)
            .unwrap()
            .iter()
            .zip(e.scanner().directions())
            .filter_map(|(p, d)| {
                let p = surface_point(&view.range, d, p.as_ref()?);
                Some((
                    p.mean.norm(),
                    (d.transpose() * p.covariance * d)[(0, 0)].sqrt(),
                ))
            })
            .collect()
    };
    let range = experiment.profile().range;
    // The quickstart's laser: σ(r) along every beam alike.
    let sigma = |r: f64| range.sigma(&Vector3::z(), r);
    let raw = along(&experiment);
    assert!(raw.iter().all(|(r, s)| (s - sigma(*r)).abs() < 1e-12));
    experiment.map_mut().pool_every_method(Pooling::Windows);
    let pooled = along(&experiment);
    assert_eq!(pooled.len(), raw.len());
    let narrowed = pooled.iter().filter(|(r, s)| *s < 0.6 * sigma(*r)).count();
    assert!(
        narrowed * 2 > pooled.len(),
        "{narrowed} of {} hits pooled",
        pooled.len()
    );
}

#[test]
fn maps_draw_pooled_beams_without_the_slide_and_the_nees_keeps_it() {
    // With the chain exact (blind), a beam's σ along its scene-frame
    // line is the σ of the camera-frame point the map drew: the pooled
    // range's own (the plane's prediction), not the hit's, which adds
    // the slide r σ_a tan θ on a slanted plane.
    let mut experiment = quickstart();
    experiment.map_mut().pool_every_method(Pooling::Windows);
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let view = experiment.mapper_view();
    let scan = &run.scans[0];
    let measured = measured_ranges(&view, &experiment.scanner().layout, scan).unwrap();
    let all = [measured.clone()];
    let extras = BuildExtras {
        measured: Some(&all),
        done: None,
        max_bytes: None,
        phases: None,
    };
    let prepared = PreparedScan::new(&view, &run.scans, 0, extras, Method::Blind).unwrap();
    let origin = prepared.origin.mean;
    let (mut pooled, mut slanted) = (0, 0);
    for (k, (p, d)) in measured
        .iter()
        .zip(experiment.scanner().directions())
        .enumerate()
    {
        let Some(p) = p else { continue };
        let end = prepared.beam_end(&view, Some(&measured), k, &Vector3::zeros());
        let Some(BeamEnd::Hit { point, covariance }) = end else {
            panic!("beam {k} measured a range and is not a hit");
        };
        let v = (point - origin).normalize();
        let drawn = (v.transpose() * covariance * v)[(0, 0)].sqrt();
        assert!(
            (drawn - p.sigma).abs() <= 1e-9 * p.sigma,
            "beam {k}: σ {drawn} drawn, {} measured",
            p.sigma
        );
        let hit = hit_point(&view.range, d, p);
        let hit_sigma = (d.transpose() * hit.covariance * d)[(0, 0)].sqrt();
        assert!(hit_sigma >= p.sigma * (1.0 - 1e-12));
        pooled += usize::from(p.normal.is_some());
        slanted += usize::from(hit_sigma > 1.1 * p.sigma);
    }
    assert!(pooled > 1000, "{pooled} pooled beams");
    assert!(slanted * 10 > pooled, "{slanted} of {pooled} with a slide");
}

#[test]
fn maps_draw_a_raw_beam_with_its_own_noise_and_its_frames_scale() {
    // Unpooled, with the chain exact (blind), a beam's σ along its line is
    // its range noise and the frame's scale error: √(σ(r)² + (s_σ r)²).
    let mut experiment = quickstart();
    experiment.map_mut().pool_every_method(Pooling::Off);
    experiment.profile_mut().range.scale_sigma = 0.01;
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let view = experiment.mapper_view();
    let prepared =
        PreparedScan::new(&view, &run.scans, 0, BuildExtras::default(), Method::Blind).unwrap();
    let origin = prepared.origin.mean;
    let range = experiment.profile().range;
    let mut hits = 0;
    for (k, (m, d)) in run.scans[0]
        .measurements
        .iter()
        .zip(experiment.scanner().directions())
        .enumerate()
    {
        let Some(BeamEnd::Hit { point, covariance }) =
            prepared.beam_end(&view, None, k, &Vector3::zeros())
        else {
            continue;
        };
        let v = (point - origin).normalize();
        let drawn = (v.transpose() * covariance * v)[(0, 0)].sqrt();
        let expected = range.sigma(d, m.range).hypot(0.01 * m.range);
        assert!(
            (drawn - expected).abs() <= 1e-9 * expected,
            "beam {k}: σ {drawn} drawn, {expected} expected"
        );
        hits += 1;
    }
    assert!(hits > 1000, "{hits} hits");
}

#[test]
fn the_ray_update_ends_its_rays_at_the_pooled_points() {
    let mut experiment = quickstart();
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let resolution = 0.02;
    let ray_map = |e: &Experiment| {
        build_map(
            &e.mapper_view(),
            &run.scans,
            Method::RayUpdate,
            resolution,
            &Vector3::zeros(),
        )
        .unwrap()
        .leaves()
    };
    let raw = ray_map(&experiment);
    experiment.map_mut().pool_every_method(Pooling::Faces);
    let view = experiment.mapper_view();
    // OctoMap's update, scan by scan, of rays ending at the pooled points.
    let mut expected = Octree::new(resolution);
    for scan in &run.scans {
        let points = measured_ranges(&view, &experiment.scanner().layout, scan).unwrap();
        let pose = scan.chain.scene_from_camera();
        let (mut hits, mut misses) = (Vec::new(), Vec::new());
        for ((m, d), p) in scan
            .measurements
            .iter()
            .zip(experiment.scanner().directions())
            .zip(&points)
        {
            match m.status {
                BeamStatus::Hit => hits.push(pose * Point3::from(d * p.unwrap().range)),
                BeamStatus::NoReturn => misses.push(pose.rotation * d),
                _ => {}
            }
        }
        let origin = Point3::from(pose.translation.vector);
        RayUpdater::new(view.settings.update).insert_scan(
            &mut expected,
            &origin,
            &hits,
            &misses,
            view.max_range,
        );
    }
    let pooled = ray_map(&experiment);
    assert!(
        pooled == expected.leaves(),
        "the ray update ignored the pooled points"
    );
    assert!(pooled != raw);
    // The same when the run hands every method the scans' points.
    let measured: Vec<_> = run
        .scans
        .iter()
        .map(|s| measured_ranges(&view, &experiment.scanner().layout, s).unwrap())
        .collect();
    let extras = BuildExtras {
        measured: Some(&measured),
        done: None,
        max_bytes: None,
        phases: None,
    };
    let shared = build_map_with(
        &view,
        &run.scans,
        extras,
        Method::RayUpdate,
        resolution,
        &Vector3::zeros(),
    )
    .unwrap();
    assert!(shared.leaves() == pooled);
}

#[test]
fn the_experiments_sigma_set_reaches_the_maps() {
    let mut experiment = quickstart();
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let map = |e: &Experiment, method| {
        let tree = build_map(
            &e.mapper_view(),
            &run.scans,
            method,
            0.02,
            &Vector3::zeros(),
        );
        crate::mapping::octomap_io::to_ot(&tree.unwrap())
    };
    let paper = map(&experiment, Method::Unscented);
    let blind = map(&experiment, Method::Blind);
    // α = 1, β = κ = 0 is the paper's set: λ = 0, the same spread √n
    // and weights 1/2n, a centre point of weight 0.
    *experiment.sigma_set_mut() = SigmaSet::Scaled {
        alpha: 1.0,
        beta: 0.0,
        kappa: 0.0,
    };
    assert!(map(&experiment, Method::Unscented) == paper);
    // A narrower set with β = 2 weighs the centre point: another map,
    // and only for the sigma-point methods.
    *experiment.sigma_set_mut() = SigmaSet::Scaled {
        alpha: 0.5,
        beta: 2.0,
        kappa: 0.0,
    };
    assert!(map(&experiment, Method::Unscented) != paper);
    assert!(map(&experiment, Method::Blind) == blind);
}

#[test]
fn a_map_that_outgrows_its_memory_budget_stops_with_one_line() {
    // The quickstart's maps take about a megabyte; with a budget of 100 kB
    // each method stops after the scan that passed it, naming the limit.
    let experiment = quickstart();
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let view = experiment.mapper_view();
    for method in [Method::RayUpdate, Method::Unscented] {
        let build = |max_bytes| {
            let extras = BuildExtras {
                max_bytes,
                ..BuildExtras::default()
            };
            build_map_with(&view, &run.scans, extras, method, 0.01, &Vector3::zeros())
        };
        let whole = build(None).unwrap();
        assert!(whole.pool_bytes() > 100_000, "{method}");
        let err = build(Some(100_000)).err().unwrap().to_string();
        assert!(
            err.contains("the map outgrew") && err.contains("after scan 1 of 6"),
            "{method}: {err}"
        );
        assert_eq!(err.lines().count(), 1);
    }
}

#[test]
fn a_map_times_its_phases_and_is_the_same_map() {
    let experiment = quickstart();
    let run = crate::experiment::simulate(&experiment, 1, |_| {}).unwrap();
    let view = experiment.mapper_view();
    let build = |extras| {
        build_map_with(
            &view,
            &run.scans,
            extras,
            Method::Unscented,
            0.05,
            &Vector3::zeros(),
        )
        .unwrap()
    };
    let times = PhaseTimes::default();
    let timed = build(BuildExtras {
        phases: Some(&times),
        ..BuildExtras::default()
    });
    assert!(timed == build(BuildExtras::default()));
    for phase in Phase::ALL {
        assert!(times.seconds(phase) > 0.0, "{}", phase.as_str());
    }
    assert!(Phase::RAY_UPDATE.iter().all(|&p| times.seconds(p) == 0.0));
    // The ray update has none of these steps, but its own two.
    for method in [Method::RayUpdate, Method::RayUpdateDiscrete] {
        let ray_times = PhaseTimes::default();
        let ray_build = |extras| {
            build_map_with(&view, &run.scans, extras, method, 0.05, &Vector3::zeros()).unwrap()
        };
        let timed = ray_build(BuildExtras {
            phases: Some(&ray_times),
            ..BuildExtras::default()
        });
        assert!(timed == ray_build(BuildExtras::default()), "{method}");
        assert!(Phase::ALL.iter().all(|&p| ray_times.seconds(p) == 0.0));
        for phase in Phase::RAY_UPDATE {
            assert!(
                ray_times.seconds(phase) > 0.0,
                "{method}: {}",
                phase.as_str()
            );
        }
    }
}
