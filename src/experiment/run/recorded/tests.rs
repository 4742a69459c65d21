use super::*;
use crate::experiment::output::export::scan_nodes;
use crate::experiment::shipped_quickstart as quickstart;
use crate::experiment::simulate;
use crate::mapping::build_map;
use crate::mapping::cloud_grids::tests::raster;
use crate::mapping::measured::measured_ranges;
use crate::mapping::pooling::Pooling;
use std::path::Path;

/// The scans of a simulated run, handed over as a recorded graph (as `sigmap
/// export` writes them), map as sigmap maps its own scans: the ray update
/// cell for cell, and an OPDF method — with the pose covariances zero, so
/// that the chain's factorisation does not matter — to the same cells and
/// log-odds: the grids recovered from the points are the scanner's own.
#[test]
fn recorded_scans_map_as_the_simulated_scans_do() {
    let experiment = quickstart();
    let mut run = simulate(&experiment, 1, |_| {}).unwrap();
    run.scans.truncate(2);
    for scan in &mut run.scans {
        scan.chain.world_from_scene.covariance = Matrix6::zeros();
        scan.chain.world_from_robot.covariance = Matrix6::zeros();
        scan.chain.robot_from_camera.covariance = Matrix6::zeros();
    }
    let view = experiment.mapper_view();
    let offset = Vector3::zeros();
    let nodes = scan_nodes(&view, &run.scans, &offset);
    let mut profile = experiment.profile().clone();
    profile.world_from_scene = Matrix6::zeros();
    profile.robot_from_camera = Matrix6::zeros();
    profile.arm = ArmError::Pose(Matrix6::zeros());
    let resolution = 0.02;
    // With beam pooling too: the bins are the scanner's raster, so each
    // beam is pooled with the same neighbours.
    let mut experiment = experiment;
    for pooling in [Pooling::Off, Pooling::Faces, Pooling::Windows] {
        experiment.map_mut().pool_every_method(pooling);
        let view = experiment.mapper_view();
        for method in [Method::RayUpdate, Method::Unscented] {
            let ours = build_map(&view, &run.scans, method, resolution, &offset).unwrap();
            let options = RecordedOptions {
                method,
                resolution,
                max_range: Some(experiment.scanner().max_range),
                angular_step: None,
            };
            let theirs =
                map_recorded(&nodes, &profile, experiment.map(), &options, |_| {}).unwrap();
            let (mut cells, mut differ) = (0usize, 0usize);
            ours.visit_leaves(|leaf| {
                cells += 1;
                let other = theirs.query(&leaf.key, leaf.depth);
                if other.is_none_or(|v| (v - leaf.value).abs() > 1e-3) {
                    differ += 1;
                }
            });
            eprintln!("{method:?} ({pooling:?}): {differ} of {cells} leaves differ");
            assert!(cells > 1000);
            assert_eq!(differ, 0, "{method:?} ({pooling:?})");
            let leaves = (ours.stats().leaves, theirs.stats().leaves);
            assert_eq!(leaves.0, leaves.1, "{method:?} ({pooling:?})");
        }
    }
    // Progress: once per node, in order.
    let seen = std::sync::Mutex::new(Vec::new());
    let options = RecordedOptions {
        method: Method::Jacobian,
        resolution,
        max_range: None,
        angular_step: Some(0.5f64.to_radians()),
    };
    map_recorded(&nodes, &profile, experiment.map(), &options, |k| {
        seen.lock().unwrap().push(k);
    })
    .unwrap();
    assert_eq!(seen.into_inner().unwrap(), vec![1, 2]);
}

#[test]
fn a_profile_with_joint_errors_is_refused() {
    let experiment = quickstart();
    assert!(matches!(experiment.profile().arm, ArmError::Joints(_)));
    let node = ScanNode {
        pixels: None,
        id: 0,
        map_from_sensor: crate::geometry::Isometry3::identity(),
        points: vec![Point3::new(0.0, 0.0, 1.0)],
    };
    let err = node_chain(&node, experiment.profile())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("joint_sigma") && err.contains("collaborative.toml"),
        "{err}"
    );
}

/// Pooling needs the scanner's raster: bins twice the raster step hold
/// two points each, and the map is refused with what to do.
#[test]
fn pooling_a_cloud_needs_one_point_per_bin() {
    let points = raster(0.5, 30, 20, |_| true);
    let node = ScanNode {
        pixels: None,
        id: 7,
        map_from_sensor: crate::geometry::Isometry3::identity(),
        points,
    };
    let experiment = quickstart();
    let settings = MapSettings {
        beam_pooling: Pooling::Faces,
        ray_pooling: Pooling::Faces,
        ..*experiment.map()
    };
    let exact = UncertainPose::from_sigmas(Pose::identity(), [0.0; 6]);
    let scan = Scan {
        viewpoint: 7,
        joints: Vec::new(),
        chain: NominalChain {
            world_from_scene: exact,
            world_from_robot: exact,
            robot_from_camera: exact,
        },
        measurements: node
            .points
            .iter()
            .map(|p| point_measurement(p, f64::INFINITY))
            .collect(),
    };
    let points_with = |step: Option<f64>| {
        let layout = node_layout(&node, step.map(f64::to_radians)).unwrap();
        let view = MapperView {
            layouts: Layouts::PerScan(std::slice::from_ref(&layout)),
            range: experiment.profile().range,
            max_range: f64::INFINITY,
            settings: &settings,
            sigma_set: SigmaSet::Paper,
        };
        measured_ranges(&view, &layout, &scan)
    };
    let pooled = points_with(None).unwrap();
    assert!(pooled.iter().all(Option::is_some));
    let err = points_with(Some(1.0)).unwrap_err();
    assert!(
        err.contains("scan 7")
            && err.contains("one point per angular bin")
            && err.contains("angular step"),
        "{err}"
    );
}

/// A profile whose pose error is absurd (a variance of infinity) is refused
/// for recorded scans as it is for an experiment, naming the profile.
#[test]
fn recorded_scans_refuse_an_absurd_profile() {
    let mut profile = crate::experiment::shipped_poses_profile();
    profile.arm = ArmError::Pose(Matrix6::identity() * 1e200 * 1e200);
    let node = ScanNode {
        pixels: None,
        id: 0,
        map_from_sensor: crate::geometry::Isometry3::identity(),
        points: vec![Point3::new(0.0, 0.0, 1.0)],
    };
    let options = RecordedOptions {
        method: Method::Unscented,
        resolution: 0.05,
        max_range: None,
        angular_step: None,
    };
    let err = map_recorded(&[node], &profile, &MapSettings::default(), &options, |_| {})
        .map(|_| ())
        .expect_err("refused")
        .to_string();
    assert!(
        err.contains("collaborative_poses.toml") && err.contains("exceeds 1 m"),
        "{err}"
    );
}

/// One point of a recorded cloud far outside any scene (a corrupt value)
/// would make the uncertainty-aware merge of its scan take gigabytes: the
/// map is refused before it is built, naming the scan and the reach. With a
/// `--max-range` that point is a beam that returned nothing and the map is
/// made; the ray update maps it as it is.
#[test]
fn a_cloud_reaching_far_past_its_scene_is_refused_before_the_merge() {
    let profile = crate::experiment::shipped_poses_profile();
    let mut points = raster(0.5, 24, 16, |_| true);
    points[40] = Point3::from(points[40].coords.normalize() * 1e100);
    let nodes = [ScanNode {
        pixels: None,
        id: 7,
        map_from_sensor: crate::geometry::Isometry3::identity(),
        points,
    }];
    let map = |method, max_range| {
        let options = RecordedOptions {
            method,
            resolution: 0.02,
            max_range,
            angular_step: None,
        };
        map_recorded(&nodes, &profile, &MapSettings::default(), &options, |_| {})
    };
    let err = map(Method::Unscented, None)
        .expect_err("refused")
        .to_string();
    assert!(
        err.contains("method unscented, scan 0: its beams reach 1.")
            && err.contains("e100 m at resolution 0.02 m"),
        "{err}"
    );
    assert!(map(Method::Unscented, Some(3.0)).is_ok());
    assert!(map(Method::RayUpdate, None).is_ok());
}

#[test]
fn more_points_than_a_map_can_hold_are_refused_naming_the_file() {
    let path = Path::new("scans.graph");
    assert!(check_point_count(path, MAX_RECORDED_POINTS).is_ok());
    let e = check_point_count(path, MAX_RECORDED_POINTS + 1)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("scans.graph") && e.contains("100000001 points") && e.contains("split"),
        "{e}"
    );
}
