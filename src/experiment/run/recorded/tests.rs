use super::*;
use crate::experiment::output::export::scan_nodes;
use crate::experiment::shipped_quickstart as quickstart;
use crate::experiment::simulate;
use crate::mapping::build_map;
use crate::mapping::measured::measured_ranges;
use crate::mapping::pooling::Pooling;
use std::path::Path;

/// Points on a regular (horizontal, vertical) raster in the camera
/// convention, `d(h, v) = (cos v sin h, sin v, cos v cos h)`.
fn raster(step_deg: f64, columns: usize, rows: usize, keep: impl Fn(usize) -> bool) -> Vec<Point3> {
    let step = step_deg.to_radians();
    let mut points = Vec::new();
    for row in 0..rows {
        for column in 0..columns {
            let (h, v) = ((column as f64 - 10.3) * step, (row as f64 - 7.0) * step);
            if keep(row * columns + column) {
                let r = 1.0 + 0.1 * (column as f64 * 0.37).sin();
                points.push(Point3::new(
                    r * v.cos() * h.sin(),
                    r * v.sin(),
                    r * v.cos() * h.cos(),
                ));
            }
        }
    }
    points
}

#[test]
fn the_spacing_of_a_raster_is_its_step() {
    // 1 point in 7 dropped: the median nearest neighbour is still the step.
    let points = raster(0.5, 60, 40, |i| i % 7 != 3);
    let frames = grid_frames(&points);
    assert_eq!(frames.len(), 1, "all in front: one camera grid");
    let (frame, members) = &frames[0];
    assert_eq!(members.len(), points.len());
    let angles: Vec<(f64, f64)> = members
        .iter()
        .map(|&i| {
            let (_, az, el) = spherical(&(frame.transpose() * points[i].coords));
            (az, el)
        })
        .collect();
    let step = median_spacing(&angles).unwrap();
    assert!(
        (step - 0.5f64.to_radians()).abs() < 1e-9,
        "{}",
        step.to_degrees()
    );
    let (azimuth, elevation) = bin_axes(&angles, None).unwrap().unwrap();
    assert_eq!((azimuth.count, elevation.count), (60, 40));
    // Every beam sits at the centre of its own bin.
    let mut seen = std::collections::HashSet::new();
    for (az, el) in &angles {
        let (a, e) = (azimuth.index(*az), elevation.index(*el));
        assert!((azimuth.centre(a as usize) - az).abs() < 1e-9);
        assert!((elevation.centre(e as usize) - el).abs() < 1e-9);
        assert!(seen.insert((a, e)), "one beam per bin");
    }
    // Too fine a step is refused before the bins are allocated.
    let err = bin_axes(&angles, Some(1e-7)).unwrap_err().to_string();
    assert!(err.contains("--angular-step"), "{err}");
}

#[test]
fn a_spinning_lidar_gets_two_half_grids_about_its_axis() {
    // 360 degrees about z, +-15 degrees of elevation.
    let mut points = Vec::new();
    for i in 0..720 {
        for j in 0..16 {
            let (h, v) = (
                (i as f64 * 0.5).to_radians(),
                (-15.0 + 2.0 * j as f64).to_radians(),
            );
            points.push(Point3::new(
                3.0 * v.cos() * h.cos(),
                3.0 * v.cos() * h.sin(),
                3.0 * v.sin(),
            ));
        }
    }
    let frames = grid_frames(&points);
    assert_eq!(frames.len(), 2);
    let mut total = 0;
    for (frame, members) in &frames {
        assert!((frame.determinant() - 1.0).abs() < 1e-12, "a rotation");
        assert_eq!(Vector3::from(frame.column(2)), Vector3::z(), "pole along z");
        for &i in members {
            let (_, az, el) = spherical(&(frame.transpose() * points[i].coords));
            assert!(az.abs() <= std::f64::consts::FRAC_PI_2 + 1e-12);
            assert!(el.abs() <= 15.0f64.to_radians() + 1e-9);
        }
        total += members.len();
    }
    assert_eq!(total, points.len());
}

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
            range: &experiment.profile().range,
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
