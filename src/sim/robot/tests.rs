use super::*;
use nalgebra::Matrix4;
use rand::{Rng, SeedableRng};
use std::f64::consts::{FRAC_PI_2, PI};

fn robots_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("robots")
}

/// Standard DH link transform `Rz(θ) Tz(d) Tx(a) Rx(α)`, written out by hand
/// so that the test does not share code with the URDF route.
fn dh_link(theta: f64, d: f64, a: f64, alpha: f64) -> Matrix4<f64> {
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = alpha.sin_cos();
    Matrix4::new(
        ct,
        -st * ca,
        st * sa,
        a * ct, //
        st,
        ct * ca,
        -ct * sa,
        a * st, //
        0.0,
        sa,
        ca,
        d, //
        0.0,
        0.0,
        0.0,
        1.0,
    )
}

fn dh_chain(table: &[(f64, f64, f64)], q: &[f64]) -> Matrix4<f64> {
    table
        .iter()
        .zip(q)
        .fold(Matrix4::identity(), |acc, (&(d, a, alpha), &theta)| {
            acc * dh_link(theta, d, a, alpha)
        })
}

fn translation_z(z: f64) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m[(2, 3)] = z;
    m
}

fn random_config(chain: &KinematicChain, rng: &mut impl Rng) -> Vec<f64> {
    chain
        .limits()
        .iter()
        .map(|&(lo, hi)| rng.random_range(lo.max(-PI)..hi.min(PI)))
        .collect()
}

/// Universal Robots' UR5 DH table (d, a, alpha).
const UR5_DH: [(f64, f64, f64); 6] = [
    (0.089159, 0.0, FRAC_PI_2),
    (0.0, -0.425, 0.0),
    (0.0, -0.39225, 0.0),
    (0.10915, 0.0, FRAC_PI_2),
    (0.09465, 0.0, -FRAC_PI_2),
    (0.0823, 0.0, 0.0),
];

#[test]
fn ur5_forward_kinematics_matches_published_dh() {
    let table = UR5_DH;
    let robot = Robot::load(&robots_dir().join("ur5.urdf")).unwrap();
    let from_base_link = robot.chain("base_link", "tool0").unwrap();
    let mut rz_pi = Matrix4::identity();
    rz_pi[(0, 0)] = -1.0;
    rz_pi[(1, 1)] = -1.0;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut configs = vec![vec![0.0; 6], vec![0.1, -1.2, 1.5, -0.4, 1.1, 2.0]];
    configs.extend((0..20).map(|_| random_config(&from_base_link, &mut rng)));
    for q in &configs {
        let dh = dh_chain(&table, q);
        let urdf = from_base_link.forward(q).unwrap().to_homogeneous();
        let err = (urdf - rz_pi * dh).abs().max();
        assert!(err < 1e-9, "q = {q:?}: |FK - Rz(pi) DH| = {err:e}");
    }
}

#[test]
fn puma560_forward_kinematics_matches_corke_dh() {
    let table = [
        (0.0, 0.0, FRAC_PI_2),
        (0.0, 0.4318, 0.0),
        (0.15005, 0.0203, -FRAC_PI_2),
        (0.4318, 0.0, FRAC_PI_2),
        (0.0, 0.0, -FRAC_PI_2),
        (0.0, 0.0, 0.0),
    ];
    let robot = Robot::load(&robots_dir().join("puma560.urdf")).unwrap();
    let chain = robot.chain("base_link", "flange").unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
    let mut configs = vec![
        vec![0.0; 6],
        vec![0.0, FRAC_PI_2, -FRAC_PI_2, 0.0, 0.0, 0.0],
    ];
    configs.extend((0..20).map(|_| random_config(&chain, &mut rng)));
    for q in &configs {
        let expected = translation_z(0.66) * dh_chain(&table, q) * translation_z(0.05625);
        let err = (chain.forward(q).unwrap().to_homogeneous() - expected)
            .abs()
            .max();
        assert!(err < 1e-9, "q = {q:?}: error {err:e}");
    }
}

#[test]
fn ur5_base_frame_is_the_dh_base() {
    let robot = Robot::load(&robots_dir().join("ur5.urdf")).unwrap();
    let base_link_from_base = robot
        .chain("base_link", "base")
        .unwrap()
        .forward(&[])
        .unwrap();
    let q = [0.3, -0.9, 1.1, 0.2, -0.7, 0.5];
    let base_link_from_tool = robot
        .chain("base_link", "tool0")
        .unwrap()
        .forward(&q)
        .unwrap();
    let base_from_tool = base_link_from_base.inverse() * base_link_from_tool;
    // The URDF's `base` frame is the DH base: from it, the tool is the DH chain.
    let err = (base_from_tool.to_homogeneous() - dh_chain(&UR5_DH, &q))
        .abs()
        .max();
    assert!(err < 1e-9, "|base_from_tool - DH| = {err:e}");
}

#[test]
fn jacobian_matches_finite_differences() {
    let robot = Robot::load(&robots_dir().join("ur5.urdf")).unwrap();
    let chain = robot.chain("base_link", "laser").unwrap();
    let q = vec![0.4, -1.0, 1.3, -0.6, 0.8, 0.3];
    let (tip, jac) = chain.jacobian(&q);
    let h = 1e-6;
    for k in 0..6 {
        let mut plus = q.clone();
        let mut minus = q.clone();
        plus[k] += h;
        minus[k] -= h;
        let tp = chain.forward_unchecked(&plus);
        let tm = chain.forward_unchecked(&minus);
        let linear = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
        let angular = (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * h);
        assert!((linear - jac.fixed_view::<3, 1>(0, k)).norm() < 1e-8);
        assert!((angular - jac.fixed_view::<3, 1>(3, k)).norm() < 1e-8);
    }
    assert!(
        (tip.translation.vector - chain.forward_unchecked(&q).translation.vector).norm() < 1e-15
    );
}

#[test]
fn joint_limits_are_enforced() {
    let robot = Robot::load(&robots_dir().join("puma560.urdf")).unwrap();
    let chain = robot.chain("base_link", "laser").unwrap();
    let err = chain.forward(&[0.0, 0.0, 0.0, 0.0, 2.0, 0.0]).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("joint5") && msg.contains("outside its limits"),
        "{msg}"
    );
    assert!(msg.contains("puma560.urdf"));
    assert_eq!(err.exit_code(), 2);
    assert!(chain.forward(&[0.0; 5]).is_err());
    assert!(chain.forward(&[0.0, 0.0, 0.0, f64::NAN, 0.0, 0.0]).is_err());
}

#[test]
fn unknown_links_and_bad_files_are_input_errors() {
    let robot = Robot::load(&robots_dir().join("ur5.urdf")).unwrap();
    let msg = robot.chain("base_link", "gripper").unwrap_err().to_string();
    assert!(msg.contains("unknown link 'gripper'"), "{msg}");
    let msg = robot.chain("tool0", "base_link").unwrap_err().to_string();
    assert!(msg.contains("not an ancestor"), "{msg}");

    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.urdf");
    std::fs::write(
        &bad,
        "<robot name='x'><link name='a'/><joint name='j' type='revolute'>",
    )
    .unwrap();
    let err = Robot::load(&bad).unwrap_err();
    assert!(err.to_string().contains("malformed URDF"), "{err}");
    assert!(err.to_string().contains("bad.urdf"));
    let dangling = dir.path().join("dangling.urdf");
    std::fs::write(
        &dangling,
        r#"<robot name="x"><link name="a"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"#,
    )
    .unwrap();
    let msg = Robot::load(&dangling).unwrap_err().to_string();
    assert!(msg.contains("link 'b'"), "{msg}");
    // A xacro file names itself, whatever its extension; a URDF that only
    // declares the namespace or keeps a macro in a comment is read.
    let ur5 = std::fs::read_to_string(robots_dir().join("ur5.urdf")).unwrap();
    for (edit, says) in [
        (
            ur5.replacen(
                "</robot>",
                "<xacro:include filename=\"arm.xacro\"/></robot>",
                1,
            ),
            "<xacro:",
        ),
        (
            ur5.replacen("xyz=\"0 0 0.089159\"", "xyz=\"0 0 ${d1}\"", 1),
            "${",
        ),
    ] {
        let file = dir.path().join("arm.urdf");
        std::fs::write(&file, edit).unwrap();
        let msg = Robot::load(&file).unwrap_err().to_string();
        assert!(
            msg.contains("arm.urdf") && msg.contains("unexpanded xacro") && msg.contains(says),
            "{msg}"
        );
    }
    let plain = ur5
        .replacen(
            "<robot ",
            "<robot xmlns:xacro=\"http://www.ros.org/wiki/xacro\" ",
            1,
        )
        .replacen(
            "</robot>",
            "<!-- <xacro:arm prefix=\"${p}\"/> --></robot>",
            1,
        );
    let file = dir.path().join("plain.urdf");
    std::fs::write(&file, plain).unwrap();
    Robot::load(&file)
        .unwrap()
        .chain("base_link", "tool0")
        .unwrap();
    assert!(Robot::load(&dir.path().join("missing.urdf"))
        .unwrap_err()
        .to_string()
        .contains("file not found"));
}

#[test]
fn joint_angles_and_limits_in_degrees_get_a_note() {
    // The shipped arms are in radians: no note.
    for arm in ["ur5.urdf", "puma560.urdf"] {
        let robot = Robot::load(&robots_dir().join(arm)).unwrap();
        assert!(robot.notes().is_empty(), "{arm}: {:?}", robot.notes());
    }
    // The shoulder lift's origin pitch and the base's limits in degrees
    // load (they are numbers), with a note each naming the joint and the
    // radians.
    let dir = tempfile::tempdir().unwrap();
    let ur5 = std::fs::read_to_string(robots_dir().join("ur5.urdf")).unwrap();
    let degrees = ur5
        .replacen(
            "xyz=\"0 0.13585 0\" rpy=\"0 1.5707963267948966 0\"",
            "xyz=\"0 0.13585 0\" rpy=\"0 90 0\"",
            1,
        )
        .replacen(
            "lower=\"-6.283185307179586\" upper=\"6.283185307179586\"",
            "lower=\"-170\" upper=\"170\"",
            1,
        );
    let file = dir.path().join("degrees.urdf");
    std::fs::write(&file, degrees).unwrap();
    let robot = Robot::load(&file).unwrap();
    let notes = robot.notes();
    assert_eq!(notes.len(), 2, "{notes:?}");
    assert!(
        notes.iter().any(
            |n| n.contains("degrees.urdf joint 'shoulder_lift_joint' origin")
                && n.contains("[0.0000, 1.5708, 0.0000]")
        ),
        "{notes:?}"
    );
    assert!(
        notes.iter().any(
            |n| n.contains("joint 'shoulder_pan_joint': limits [-170, 170]")
                && n.contains("lower=\"-2.9671\" upper=\"2.9671\"")
        ),
        "{notes:?}"
    );
}
