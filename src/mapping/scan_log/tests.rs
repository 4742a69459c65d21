use super::*;
use crate::geometry::Vector3;

fn parse(text: &str) -> Result<Vec<ScanNode>, String> {
    parse_scan_log(text.as_bytes())
}

#[test]
fn nodes_and_points_are_read_as_log2graph_reads_them() {
    let text = "# a log\r\n\
                NODE 1 2 3 0.1 -0.2 0.3\r\n\
                0.5 0 2\n\
                \x20this line starts with a space: skipped\n\
                \n\
                -1e-3\t4 5.25\n\
                NODE 0 0 0 0 0 0\n\
                NODE -1 0 0.5 0 0 3.0\n\
                7 8 9";
    let nodes = parse(text).unwrap();
    assert_eq!(nodes.len(), 3);
    assert_eq!(nodes.iter().map(|n| n.id).collect::<Vec<_>>(), [0, 1, 2]);
    assert_eq!(
        nodes[0].points,
        [Point3::new(0.5, 0.0, 2.0), Point3::new(-1e-3, 4.0, 5.25)]
    );
    assert!(nodes[1].points.is_empty());
    // The last line has no newline: read all the same.
    assert_eq!(nodes[2].points, [Point3::new(7.0, 8.0, 9.0)]);
    // The pose is URDF's: R = Rz(yaw) Ry(pitch) Rx(roll), then the
    // translation, written out here apart from `Pose`.
    let (roll, pitch, yaw) = (0.1f64, -0.2f64, 0.3f64);
    let rx = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), roll);
    let ry = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), pitch);
    let rz = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), yaw);
    let p = Point3::new(0.5, 0.0, 2.0);
    let want = rz * ry * rx * p + Vector3::new(1.0, 2.0, 3.0);
    let got = nodes[0].map_from_sensor * p;
    assert!((got - want).norm() < 1e-12, "{got} against {want}");
}

#[test]
fn a_bad_line_is_named_with_what_is_wrong() {
    for (text, says) in [
        (
            "1 2 3\nNODE 0 0 0 0 0 0\n",
            "line 1: a point before the first",
        ),
        ("NODE 0 0 0 0 0\n", "line 1: 5 numbers where 6 belong"),
        ("NODE 0 0 0 0 0 0 0\n", "line 1: 7 numbers where 6 belong"),
        (
            "NODE 0 0 0 0 0 0\n1 2\n",
            "line 2: 2 numbers where 3 belong",
        ),
        (
            "NODE 0 0 0 0 0 0\n1 2 3 4\n",
            "line 2: 4 numbers where 3 belong",
        ),
        (
            "NODE 0 0 0 0 0 0\n1 NaN 3\n",
            "line 2: 'NaN' is not a finite number",
        ),
        (
            "NODE 0 0 inf 0 0 0\n",
            "line 1: 'inf' is not a finite number",
        ),
        (
            "NODE 0 0 0 0 0 0\n1,2,3\n",
            "line 2: '1,2,3' is not a finite number",
        ),
        (
            "NODEX 0 0 0 0 0 0\n",
            "line 1: 'NODEX' is not a finite number",
        ),
        ("# only comments\n\n", "no `NODE x y z roll pitch yaw` line"),
        ("", "no `NODE"),
    ] {
        let err = parse(text).unwrap_err();
        assert!(err.contains(says), "{text:?}: {err}");
    }
    // A long line is cut in the message.
    let long = format!("NODE 0 0 0 0 0 0\n{}\n", "9 ".repeat(200));
    let err = parse(&long).unwrap_err();
    assert!(err.len() < 250 && err.contains('…'), "{err}");
    // A line past the limit is refused without being held whole; bytes
    // that are not text are named.
    let endless = format!("NODE 0 0 0 0 0 0\n1 2 {}", "3".repeat(1 << 20));
    let err = parse(&endless).unwrap_err();
    assert!(err.starts_with("line 2: longer than 4096 bytes"), "{err}");
    let err = parse_scan_log(&b"NODE 0 0 0 0 0 0\n1 2 \xff\n"[..]).unwrap_err();
    assert_eq!(err, "line 2: not text (invalid UTF-8)");
}

#[test]
fn a_written_log_reads_back_to_its_nodes() {
    let nodes: Vec<ScanNode> = (0..3)
        .map(|i| ScanNode {
            pixels: None,
            id: i,
            map_from_sensor: Pose::new([0.1 * f64::from(i), -2.0, 1.0 / 3.0], [0.3, -1.2, 2.9])
                .to_isometry(),
            points: (0..40)
                .map(|k| {
                    let k = f64::from(k);
                    Point3::new(k.sin() / 7.0, 1e-9 * k, 0.3 + k.sqrt())
                })
                .collect(),
        })
        .collect();
    let back = parse(&to_scan_log(&nodes)).unwrap();
    assert_eq!(back.len(), nodes.len());
    for (a, b) in nodes.iter().zip(&back) {
        assert_eq!(a.id, b.id);
        assert_eq!(a.points, b.points, "points to the bit");
        let moved = (a.map_from_sensor.inverse() * b.map_from_sensor).to_homogeneous();
        let off = (moved - nalgebra::Matrix4::identity()).abs().max();
        assert!(off < 1e-14, "pose {}: {off}", a.id);
    }
}
