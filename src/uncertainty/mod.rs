//! Uncertain transforms and Gaussian input errors (MATH.md §1, §6).
//!
//! This module owns the covariance types shared by the simulator (which draws
//! errors from them) and the propagators (which push them through the chain).

mod covariance;

pub use covariance::{check_covariance, sqrt_factor, CovarianceSpec};

use crate::geometry::{Matrix6, Pose};

/// A pose known up to a zero-mean Gaussian error on its six parameters
/// (additive on the angles, MATH.md "global conventions").
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

    /// True when the covariance is zero, so the pose drops out of propagation
    /// (the paper's 42 → 30 sigma points).
    pub fn is_exact(&self) -> bool {
        self.covariance.iter().all(|v| *v == 0.0)
    }
}
