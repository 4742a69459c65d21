//! Uncertainty over the transform chain (docs/math.md §1–3, §6).
//!
//! Owns [`UncertainPose`] (a pose with a 6×6 covariance on its parameters),
//! [`UncertainChain`] (`X_s = T_1 ··· T_k X_c`, the paper's
//! `T_sw⁻¹ T_rw T_cr`), the [`Propagator`] trait with one file per method
//! ([`BlindPropagator`], [`JacobianPropagator`], [`UnscentedPropagator`],
//! [`MonteCarloPropagator`]), the normal sampler shared with the simulator,
//! and the consistency statistics (NEES, ANEES bands, coverage). It imports
//! only `geometry` and `error`.
//!
//! ```
//! use sigmap::geometry::Pose;
//! use sigmap::uncertainty::{
//!     Propagator, SigmaSet, UncertainChain, UncertainPoint, UncertainPose, UnscentedPropagator,
//! };
//! let pose = |x: f64, s: f64| UncertainPose::from_sigmas(Pose::new([x, 0.0, 0.0], [0.0; 3]), [s; 6]);
//! // world_from_scene, world_from_robot, robot_from_camera
//! let chain = UncertainChain::paper(pose(0.5, 0.001), pose(0.0, 0.002), pose(0.1, 0.001));
//! let point = UncertainPoint { mean: [0.0, 0.0, 0.6].into(), covariance: Default::default() };
//! let scene = UnscentedPropagator::new(&chain, SigmaSet::Paper).propagate(&point);
//! assert!((scene.mean.x - (0.1 - 0.5)).abs() < 1e-3 && scene.covariance[(0, 0)] > 0.0);
//! ```

mod blind;
pub mod chain;
pub mod compare;
pub mod consistency;
mod covariance;
pub mod jacobian;
pub mod monte_carlo;
pub mod quadratic;
mod range;
pub mod unscented;

pub use blind::BlindPropagator;
pub use chain::{read_chain_file, ChainLink, Gaussian3, UncertainChain, UncertainPoint};
pub use covariance::{
    check_covariance, check_pose_sigmas, sqrt_factor, standard_normal, CovarianceSpec,
    MAX_POSE_SIGMA,
};
pub use jacobian::JacobianPropagator;
pub use monte_carlo::MonteCarloPropagator;
pub use range::{RangeAxis, RangeModel};
pub use unscented::{SigmaSet, UnscentedPropagator};

use crate::geometry::{Matrix3, Matrix6, Pose, Vector3};
use rayon::prelude::*;

/// A pose known up to a zero-mean Gaussian error on its six parameters
/// (additive on the angles, docs/math.md, notation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UncertainPose {
    /// The nominal (believed) pose.
    pub mean: Pose,
    /// Covariance of `(x, y, z, roll, pitch, yaw)` in m² and rad².
    pub covariance: Matrix6,
}

impl UncertainPose {
    /// A pose known exactly.
    pub fn exact(mean: Pose) -> Self {
        Self {
            mean,
            covariance: Matrix6::zeros(),
        }
    }

    /// A pose with independent parameter errors of standard deviations
    /// `sigma` (x, y, z in m; roll, pitch, yaw in rad).
    pub fn from_sigmas(mean: Pose, sigma: [f64; 6]) -> Self {
        Self {
            mean,
            covariance: Matrix6::from_diagonal(&crate::geometry::Vector6::from(
                sigma.map(|s| s * s),
            )),
        }
    }

    /// True when the covariance is zero, so the pose drops out of propagation
    /// (the paper's 42 → 30 sigma points).
    pub fn is_exact(&self) -> bool {
        self.covariance.iter().all(|v| *v == 0.0)
    }
}

/// Maps a measured point and its covariance through an uncertain chain.
/// Implementations precompute what is constant for a chain (one viewpoint) so
/// that each point is cheap; they hold no mutable state.
pub trait Propagator: Sync {
    /// The method's name in files (`blind`, `jacobian`, `unscented`, `monte_carlo`).
    fn name(&self) -> &'static str;

    /// The output-frame mean and covariance of one point.
    fn propagate(&self, point: &UncertainPoint) -> Gaussian3;

    /// The sensor origin (the point `0`, known exactly) in the output frame.
    fn origin(&self) -> Gaussian3 {
        self.propagate(&UncertainPoint {
            mean: Vector3::zeros(),
            covariance: Matrix3::zeros(),
        })
    }

    /// Propagates `points` into the preallocated `out` (same length) on one
    /// thread, without allocating.
    fn propagate_into(&self, points: &[UncertainPoint], out: &mut [Gaussian3]) {
        for (p, o) in points.iter().zip(out.iter_mut()) {
            *o = self.propagate(p);
        }
    }
}

/// Propagates a whole scan in parallel (rayon) into `out`.
pub fn propagate_scan(
    propagator: &dyn Propagator,
    points: &[UncertainPoint],
    out: &mut [Gaussian3],
) {
    assert_eq!(points.len(), out.len(), "one output per point");
    out.par_chunks_mut(4096)
        .zip(points.par_chunks(4096))
        .for_each(|(o, p)| propagator.propagate_into(p, o));
}
