use super::*;

/// Points on a regular (horizontal, vertical) raster in the camera
/// convention, `d(h, v) = (cos v sin h, sin v, cos v cos h)`.
pub(crate) fn raster(
    step_deg: f64,
    columns: usize,
    rows: usize,
    keep: impl Fn(usize) -> bool,
) -> Vec<Point3> {
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
    let angles = grid_angles(&points, frame, members);
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
    let err = bin_axes(&angles, Some(1e-7)).unwrap_err();
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
        for (az, el) in grid_angles(&points, frame, members) {
            assert!(az.abs() <= std::f64::consts::FRAC_PI_2 + 1e-12);
            assert!(el.abs() <= 15.0f64.to_radians() + 1e-9);
        }
        total += members.len();
    }
    assert_eq!(total, points.len());
}
