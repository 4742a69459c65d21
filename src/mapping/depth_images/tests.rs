use super::*;
use crate::geometry::Vector3;

#[test]
fn pixels_become_points_as_the_benchmark_computes_them() {
    // generate_pointcloud.py: Z = d / 5000, X = (u − 319.5) Z / 525,
    // Y = (v − 239.5) Z / 525; a zero is no measurement.
    let camera = DepthCamera::TUM;
    let png = depth_png(3, &[5000, 0, 10000, 2500, 7500, 1]).unwrap();
    let node = depth_image_node(&png, &camera, 7, Isometry3::identity()).unwrap();
    assert_eq!(node.id, 7);
    let expected: Vec<Point3> = [
        (0, 0, 5000),
        (2, 0, 10000),
        (0, 1, 2500),
        (1, 1, 7500),
        (2, 1, 1),
    ]
    .into_iter()
    .map(|(u, v, d)| {
        let z = f64::from(d) / 5000.0;
        Point3::new(
            (f64::from(u) - 319.5) * z / 525.0,
            (f64::from(v) - 239.5) * z / 525.0,
            z,
        )
    })
    .collect();
    assert_eq!(node.points, expected);
    assert_eq!(
        node.points[0],
        Point3::new(-319.5 / 525.0, -239.5 / 525.0, 1.0)
    );
}

#[test]
fn colour_and_eight_bit_images_are_refused() {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 2, 1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(&[0; 6]).unwrap();
    writer.finish().unwrap();
    let e = depth_image_node(&bytes, &DepthCamera::TUM, 0, Isometry3::identity()).unwrap_err();
    assert!(
        e.contains("Rgb 8-bit image; a depth image is 16-bit grayscale"),
        "{e}"
    );
    let e = depth_image_node(b"not a png", &DepthCamera::TUM, 0, Isometry3::identity());
    assert!(e.unwrap_err().contains("not a PNG image"));
}

#[test]
fn lists_and_trajectories_are_read_as_the_benchmark_writes_them() {
    let depth = "# depth maps\n# file: 'x.bag'\n# timestamp filename\n\
                 1305031102.160407 depth/1305031102.160407.png\n\n\
                 1305031102.194330 depth/1305031102.194330.png\n";
    let images = parse_depth_list(depth).unwrap();
    assert_eq!(images.len(), 2);
    assert_eq!(
        images[1],
        (1305031102.19433, "depth/1305031102.194330.png".into())
    );
    // A quarter turn about z (qz = qw = √½): the camera's x is the map's y.
    let trajectory = "# ground truth\n# timestamp tx ty tz qx qy qz qw\n\
                      1305031102.1758 1 2 3 0 0 0.7071068 0.7071068\n";
    let poses = parse_trajectory(trajectory).unwrap();
    let (stamp, pose) = poses[0];
    assert_eq!(stamp, 1305031102.1758);
    let x = pose * Point3::new(1.0, 0.0, 0.0);
    assert!((x - Point3::new(1.0, 3.0, 3.0)).norm() < 1e-6, "{x}");
    assert!((pose.rotation * Vector3::z() - Vector3::z()).norm() < 1e-6);
    // Errors name the line.
    for (text, says) in [
        (
            "1 2 3\n",
            "line 1: expected `timestamp filename`, found 2 fields",
        ),
        ("# c\nabc depth/a.png\n", "line 2: 'abc' is not a timestamp"),
        ("NaN depth/a.png\n", "line 1: 'NaN' is not a timestamp"),
    ] {
        let e = parse_depth_list(text).unwrap_err();
        assert!(e.contains(says), "{e}");
    }
    for (text, says) in [
        (
            "1 0 0 0 0 0 0\n",
            "line 1: expected `timestamp tx ty tz qx qy qz qw`, found 6",
        ),
        ("1 0 0 0 0 0 0 2\n", "has norm 2.0000, not 1"),
        (
            "\n1 0 0 x 0 0 0 1\n",
            "line 2: a field is not a finite number",
        ),
        (
            "1 0 0 inf 0 0 0 1\n",
            "line 1: a field is not a finite number",
        ),
    ] {
        let e = parse_trajectory(text).unwrap_err();
        assert!(e.contains(says), "{e}");
    }
}

#[test]
fn each_image_takes_the_nearest_pose_within_the_gap() {
    let at = |t: f64| (t, Isometry3::identity());
    // Out of order in the file, as nothing forbids.
    let poses = [at(1.00), at(1.03), at(0.97), at(2.0)];
    let images = [0.90, 0.98, 1.011, 1.016, 1.5, 2.019, 2.021];
    assert_eq!(
        associate(&images, &poses),
        [None, Some(2), Some(0), Some(1), None, Some(3), None]
    );
    assert_eq!(associate(&[1.0], &[]), [None]);
}

#[test]
fn bad_intrinsics_are_refused() {
    assert!(DepthCamera::TUM.check().is_ok());
    let flipped = DepthCamera {
        fy: -480.0,
        ..DepthCamera::TUM
    };
    assert!(flipped.check().is_ok());
    for camera in [
        DepthCamera {
            fx: 0.0,
            ..DepthCamera::TUM
        },
        DepthCamera {
            cx: f64::NAN,
            ..DepthCamera::TUM
        },
        DepthCamera {
            scale: 0.0,
            ..DepthCamera::TUM
        },
    ] {
        assert!(camera.check().is_err(), "{camera:?}");
    }
}
