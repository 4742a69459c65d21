//! Statistical tests of the truth draw. Bounds: a variance estimated from N
//! Gaussian samples has standard error Σ_ii √(2/(N−1)), a covariance entry
//! √((Σ_ij² + Σ_ii Σ_jj)/(N−1)), a mean √(Σ_ii/N) (docs/math.md §6.5). Every entry
//! must lie within 5 standard errors (a false alarm per entry ~6e-7).

use super::*;
use crate::sim::robot::Robot;
use crate::sim::streams::{Stream, Streams};
use std::path::PathBuf;

const N: usize = 20_000;

fn assert_moments(errors: &[Vector6], expected: &Matrix6, what: &str) {
    let n = errors.len() as f64;
    let mean = errors.iter().fold(Vector6::zeros(), |a, e| a + e) / n;
    let cov = errors.iter().fold(Matrix6::zeros(), |a, e| {
        a + (e - mean) * (e - mean).transpose()
    }) / (n - 1.0);
    for i in 0..6 {
        let se = (expected[(i, i)] / n).sqrt();
        assert!(
            mean[i].abs() <= 5.0 * se + 1e-15,
            "{what}: mean[{i}] = {:e}, SE {se:e}",
            mean[i]
        );
        for j in 0..6 {
            let se = ((expected[(i, j)].powi(2) + expected[(i, i)] * expected[(j, j)]) / (n - 1.0))
                .sqrt();
            let diff = (cov[(i, j)] - expected[(i, j)]).abs();
            assert!(
                diff <= 5.0 * se + 1e-18,
                "{what}: cov[{i},{j}] = {:e} vs {:e} (SE {se:e})",
                cov[(i, j)],
                expected[(i, j)]
            );
        }
    }
}

#[test]
fn pose_draws_match_a_full_covariance() {
    let a = Matrix6::from_fn(|i, j| {
        ((i * 7 + j * 3) % 5) as f64 * 1e-3 + if i == j { 2e-3 } else { 0.0 }
    });
    let covariance = a * a.transpose();
    let nominal = UncertainPose {
        mean: Pose::new([0.4, -0.2, 0.9], [0.1, 0.3, 2.9]),
        covariance,
    };
    let streams = Streams::new(3);
    let errors: Vec<Vector6> = (0..N as u32)
        .map(|k| {
            let mut rng = streams.rng(Stream::Viewpoint(k));
            draw_pose(&nominal, &mut rng).params() - nominal.mean.params()
        })
        .collect();
    assert_moments(&errors, &covariance, "pose draw");
}

#[test]
fn joint_encoder_draws_match_fk_propagated_covariance() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("robots/ur5.urdf");
    let chain = Robot::load(&path)
        .unwrap()
        .chain("base_link", "tool0")
        .unwrap();
    let world_from_base = Pose::new([0.1, 0.0, 0.05], [0.0, 0.0, 0.4]).to_isometry();
    let q = [0.2, -1.1, 1.4, -0.9, -1.3, 0.5];
    let arm = ArmError::Joints(vec![5e-4; 6]);
    let streams = Streams::new(9);
    let mut believed = None;
    let errors: Vec<Vector6> = (0..N as u32)
        .map(|k| {
            let mut rng = streams.rng(Stream::Viewpoint(k));
            let state = draw_arm(&arm, &chain, &world_from_base, &q, &mut rng).unwrap();
            let e = parameter_error(&state.truth, &state.believed.mean);
            believed = Some(state.believed);
            e
        })
        .collect();
    let believed = believed.unwrap();
    // Γ_rw from joint errors is full, not diagonal.
    assert!(believed.covariance[(0, 1)].abs() > 1e-3 * believed.covariance[(0, 0)]);
    assert_moments(&errors, &believed.covariance, "joint draw");
    // One sigma for every joint is that sigma on each: the same draws.
    for k in 0..8 {
        let draw = |arm: &ArmError| {
            let mut rng = streams.rng(Stream::Viewpoint(k));
            draw_arm(arm, &chain, &world_from_base, &q, &mut rng).unwrap()
        };
        let (every, each) = (draw(&ArmError::EveryJoint(5e-4)), draw(&arm));
        assert_eq!(every.truth, each.truth);
        assert_eq!(every.believed.covariance, each.believed.covariance);
    }
}

#[test]
fn pose_parameter_jacobian_matches_finite_differences() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("robots/puma560.urdf");
    let chain = Robot::load(&path)
        .unwrap()
        .chain("base_link", "flange")
        .unwrap();
    let world_from_base = Pose::new([0.0, 0.3, 0.0], [0.0, 0.0, -0.7]).to_isometry();
    let q = vec![0.3, 0.6, -1.9, 0.4, 0.8, -0.3];
    let jac = pose_parameter_jacobian(&chain, &world_from_base, &q).unwrap();
    let base = Pose::from_isometry(&(world_from_base * chain.forward_unchecked(&q)));
    let h = 1e-6;
    for k in 0..6 {
        let mut plus = q.clone();
        let mut minus = q.clone();
        plus[k] += h;
        minus[k] -= h;
        let fp = parameter_error(&(world_from_base * chain.forward_unchecked(&plus)), &base);
        let fm = parameter_error(&(world_from_base * chain.forward_unchecked(&minus)), &base);
        let fd = (fp - fm) / (2.0 * h);
        assert!(
            (fd - jac.column(k)).norm() < 1e-7,
            "column {k}: {fd:?} vs {:?}",
            jac.column(k)
        );
    }
}
