//! The truth draw: what the world really is, given what the modeller believes.
//!
//! Each uncertain link is drawn as `t_true = t_nominal + δ`, `δ ~ N(0, Γ)`
//! (additive on the angles, as every propagator assumes). T_sw and T_cr errors
//! are drawn once per run, T_rw once per viewpoint, range errors per beam.

use super::profile::ArmError;
use super::robot::KinematicChain;
use crate::geometry::{rpy_rate_matrix, Isometry3, Matrix6, Pose, Vector6};
use crate::uncertainty::{sqrt_factor, standard_normal, UncertainPose};
use nalgebra::DMatrix;
use rand::Rng;
use rand_distr::StandardNormal;

/// `nominal + L ξ` with `L Lᵀ = covariance`; always consumes six normals.
pub fn draw_pose(nominal: &UncertainPose, rng: &mut impl Rng) -> Pose {
    let xi = standard_normal::<6>(rng);
    Pose::from_params(&(nominal.mean.params() + sqrt_factor(&nominal.covariance) * xi))
}

/// The arm at one viewpoint: what the modeller believes and what is true.
#[derive(Clone, Debug)]
pub struct ArmState {
    /// Nominal `world_from_robot` (T_rw) with its covariance Γ_rw.
    pub believed: UncertainPose,
    /// The true `world_from_robot`.
    pub truth: Isometry3,
}

/// Derivative of the pose parameters `(x, y, z, roll, pitch, yaw)` of
/// `world_from_base · FK(q)` with respect to `q` (6 x dof): the geometric
/// Jacobian rotated into the world, angular rows mapped to rpy rates by `E⁻¹`
/// (docs/math.md §2.1). Fails at pitch ±90°, where rpy is singular.
pub fn pose_parameter_jacobian(
    chain: &KinematicChain,
    world_from_base: &Isometry3,
    q: &[f64],
) -> Result<DMatrix<f64>, String> {
    let (base_from_tip, jac) = chain.jacobian(q);
    let pose = Pose::from_isometry(&(world_from_base * base_from_tip));
    let e = rpy_rate_matrix(&pose.rpy);
    let e_inv = e
        .try_inverse()
        .filter(|_| pose.rpy.y.cos().abs() > 1e-6)
        .ok_or_else(|| {
            "the flange pitch is ±90°, where roll/pitch/yaw is singular: move the viewpoint"
                .to_string()
        })?;
    let r = world_from_base.rotation.to_rotation_matrix().into_inner();
    let mut out = DMatrix::zeros(6, jac.ncols());
    out.view_mut((0, 0), (3, jac.ncols()))
        .copy_from(&(r * jac.rows(0, 3)));
    out.view_mut((3, 0), (3, jac.ncols()))
        .copy_from(&(e_inv * r * jac.rows(3, 3)));
    Ok(out)
}

/// The nominal arm pose with Γ_rw, and one draw of the true pose.
pub fn draw_arm(
    arm: &ArmError,
    chain: &KinematicChain,
    world_from_base: &Isometry3,
    q: &[f64],
    rng: &mut impl Rng,
) -> Result<ArmState, String> {
    let nominal = world_from_base * chain.forward_unchecked(q);
    let mean = Pose::from_isometry(&nominal);
    let covariance = arm_covariance(arm, chain, world_from_base, q)?;
    let believed = UncertainPose { mean, covariance };
    let truth = match arm.joint_sigmas(q.len()) {
        None => draw_pose(&believed, rng).to_isometry(),
        Some(sigmas) => {
            let true_q: Vec<f64> = q
                .iter()
                .zip(sigmas)
                .map(|(qi, s)| qi + s * rng.sample::<f64, _>(StandardNormal))
                .collect();
            world_from_base * chain.forward_unchecked(&true_q)
        }
    };
    Ok(ArmState { believed, truth })
}

/// Γ_rw of the arm at joints `q`: a pose error as given, a joint error
/// `J Σ_q Jᵀ` with `J` the [`pose_parameter_jacobian`] (docs/math.md §2.1).
pub fn arm_covariance(
    arm: &ArmError,
    chain: &KinematicChain,
    world_from_base: &Isometry3,
    q: &[f64],
) -> Result<Matrix6, String> {
    let sigmas = match arm {
        ArmError::Pose(covariance) => return Ok(*covariance),
        ArmError::Joints(sigmas) => sigmas.clone(),
        ArmError::EveryJoint(sigma) => vec![*sigma; q.len()],
    };
    if sigmas.len() != q.len() {
        return Err(format!(
            "joint_sigma has {} values but the arm has {} joints",
            sigmas.len(),
            q.len()
        ));
    }
    let jac = pose_parameter_jacobian(chain, world_from_base, q)?;
    let sigma_q = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        sigmas.len(),
        sigmas.iter().map(|s| s * s),
    ));
    let full = &jac * sigma_q * jac.transpose();
    Ok(Matrix6::from_fn(|i, j| 0.5 * (full[(i, j)] + full[(j, i)])))
}

/// The parameter error `t_true − t_nominal`, angles wrapped to (−π, π].
pub fn parameter_error(truth: &Isometry3, nominal: &Pose) -> Vector6 {
    let mut d = Pose::from_isometry(truth).params() - nominal.params();
    for k in 3..6 {
        d[k] = (d[k] + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
            - std::f64::consts::PI;
    }
    d
}

#[cfg(test)]
mod tests;
