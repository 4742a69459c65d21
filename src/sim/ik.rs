//! Inverse kinematics by damped least squares on the geometric Jacobian, with
//! deterministic random restarts.

use super::robot::KinematicChain;
use crate::geometry::{Isometry3, Vector3};
use nalgebra::{DMatrix, DVector, Unit};
use rand::{Rng, SeedableRng};

/// What the tip frame must reach, in the chain's base frame.
#[derive(Clone, Debug)]
pub enum IkTarget {
    /// A full pose of the tip.
    Pose(Isometry3),
    /// Tip origin at `position` with its +z axis along `boresight`; the roll
    /// about the boresight is free (5 constraints).
    LookAt {
        /// Where the tip's origin must be.
        position: Vector3,
        /// Where its +z axis must point.
        boresight: Unit<Vector3>,
    },
}

/// Settings of the solver.
#[derive(Clone, Debug)]
pub struct IkOptions {
    /// Number of starts (the first from `initial`, the others random within limits).
    pub restarts: usize,
    /// Iterations per start.
    pub max_iterations: usize,
    /// Position tolerance (m).
    pub tolerance_m: f64,
    /// Orientation tolerance (rad).
    pub tolerance_rad: f64,
    /// Seed of the restart configurations (deterministic).
    pub seed: u64,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            restarts: 32,
            max_iterations: 300,
            tolerance_m: 1e-9,
            tolerance_rad: 1e-9,
            seed: 0,
        }
    }
}

/// The best residuals reached when no start converged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkFailure {
    /// Smallest position error reached (m).
    pub position_error: f64,
    /// Orientation error at that solution (rad).
    pub orientation_error: f64,
}

/// Position and orientation error vectors of `current` against `target`.
fn residual(current: &Isometry3, target: &IkTarget) -> (Vector3, Vector3) {
    match target {
        IkTarget::Pose(goal) => (
            goal.translation.vector - current.translation.vector,
            (goal.rotation * current.rotation.inverse()).scaled_axis(),
        ),
        IkTarget::LookAt {
            position,
            boresight,
        } => {
            let z = current.rotation * Vector3::z();
            let cross = z.cross(boresight);
            // atan2 keeps full precision near 0 and past 90°.
            let angle = cross.norm().atan2(z.dot(boresight));
            let axis = if cross.norm() > 1e-12 {
                cross.normalize()
            } else {
                (current.rotation * Vector3::x()).normalize()
            };
            (
                position - current.translation.vector,
                axis * if angle > 1e-12 { angle } else { 0.0 },
            )
        }
    }
}

/// Solves for a configuration within the joint limits. `initial` (if given)
/// is the first start.
pub fn solve(
    chain: &KinematicChain,
    target: &IkTarget,
    initial: Option<&[f64]>,
    options: &IkOptions,
) -> Result<Vec<f64>, IkFailure> {
    let limits = chain.limits();
    let dof = chain.dof();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(options.seed);
    let mut best = IkFailure {
        position_error: f64::INFINITY,
        orientation_error: f64::INFINITY,
    };
    for start in 0..options.restarts.max(1) {
        let mut q: Vec<f64> = match (start, initial) {
            (0, Some(q0)) if q0.len() == dof => q0.to_vec(),
            _ => limits
                .iter()
                .map(|&(lo, hi)| {
                    let (lo, hi) = (lo.max(-std::f64::consts::PI), hi.min(std::f64::consts::PI));
                    if start == 0 {
                        0.5 * (lo + hi)
                    } else {
                        rng.random_range(lo..=hi)
                    }
                })
                .collect(),
        };
        for _ in 0..options.max_iterations {
            let (tip, jac) = chain.jacobian(&q);
            let (dp, dr) = residual(&tip, target);
            if dp.norm() < options.tolerance_m && dr.norm() < options.tolerance_rad {
                return Ok(q);
            }
            let err = DVector::from_iterator(6, dp.iter().chain(dr.iter()).copied());
            // Damped least squares: dq = Jᵀ (J Jᵀ + λ² I)⁻¹ e, damping fading near the goal.
            let lambda = if err.norm() > 1e-3 { 0.05 } else { 1e-5 };
            let jjt = &jac * jac.transpose() + DMatrix::identity(6, 6) * lambda * lambda;
            let Some(solved) = jjt.cholesky().map(|c| c.solve(&err)) else {
                break;
            };
            let mut dq = jac.transpose() * solved;
            let step = dq.amax();
            if step > 0.3 {
                dq *= 0.3 / step;
            }
            for ((value, delta), &(lo, hi)) in q.iter_mut().zip(dq.iter()).zip(&limits) {
                *value = (*value + delta).clamp(lo, hi);
            }
        }
        let (dp, dr) = residual(&chain.forward_unchecked(&q), target);
        if dp.norm() < best.position_error {
            best = IkFailure {
                position_error: dp.norm(),
                orientation_error: dr.norm(),
            };
        }
    }
    Err(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::robot::Robot;
    use std::path::PathBuf;

    fn chain(file: &str) -> KinematicChain {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("robots")
            .join(file);
        Robot::load(&path)
            .unwrap()
            .chain("base_link", "laser")
            .unwrap()
    }

    #[test]
    fn reaches_a_pose_that_fk_produced() {
        for file in ["ur5.urdf", "puma560.urdf"] {
            let chain = chain(file);
            let q_true = [0.3, 0.5, -1.1, 0.4, 0.7, -0.2];
            let goal = chain.forward(&q_true).unwrap();
            let q = solve(&chain, &IkTarget::Pose(goal), None, &IkOptions::default()).unwrap();
            chain.check(&q).unwrap();
            let reached = chain.forward(&q).unwrap();
            assert!(
                (reached.translation.vector - goal.translation.vector).norm() < 1e-9,
                "{file}"
            );
            assert!(reached.rotation.angle_to(&goal.rotation) < 1e-9, "{file}");
        }
    }

    #[test]
    fn look_at_points_the_boresight() {
        let chain = chain("ur5.urdf");
        let boresight = Unit::new_normalize(Vector3::new(0.2, 0.1, -1.0));
        let target = IkTarget::LookAt {
            position: Vector3::new(0.45, 0.2, 0.6),
            boresight,
        };
        let q = solve(&chain, &target, None, &IkOptions::default()).unwrap();
        let tip = chain.forward(&q).unwrap();
        assert!((tip.translation.vector - Vector3::new(0.45, 0.2, 0.6)).norm() < 1e-9);
        assert!(((tip.rotation * Vector3::z()) - boresight.into_inner()).norm() < 1e-9);
    }

    #[test]
    fn unreachable_target_reports_residual() {
        let chain = chain("ur5.urdf");
        let target = IkTarget::LookAt {
            position: Vector3::new(3.0, 0.0, 0.5),
            boresight: Vector3::x_axis(),
        };
        let options = IkOptions {
            restarts: 4,
            ..IkOptions::default()
        };
        let failure = solve(&chain, &target, None, &options).unwrap_err();
        assert!(failure.position_error > 1.5, "{failure:?}");
    }
}
