//! "Blind" propagation (docs/math.md §6.1): the chain taken as exact, the
//! measurement covariance only rotated into the scene. The previous work the
//! paper extends, kept as a method to show what ignoring pose error costs.

use super::chain::{Gaussian3, UncertainChain, UncertainPoint};
use super::Propagator;
use crate::geometry::{Isometry3, Matrix3};
use nalgebra::Point3;

/// "Blind" propagation: the chain taken as exact, only the measurement
/// covariance mapped by the nominal rotation (the previous work the paper
/// extends).
#[derive(Clone, Debug)]
pub struct BlindPropagator {
    nominal: Isometry3,
    rotation: Matrix3,
}

impl BlindPropagator {
    /// The nominal chain of `chain`.
    pub fn new(chain: &UncertainChain) -> Self {
        let nominal = chain.nominal();
        Self {
            nominal,
            rotation: nominal.rotation.to_rotation_matrix().into_inner(),
        }
    }
}

impl Propagator for BlindPropagator {
    fn name(&self) -> &'static str {
        "blind"
    }

    #[inline]
    fn propagate(&self, point: &UncertainPoint) -> Gaussian3 {
        Gaussian3 {
            mean: (self.nominal * Point3::from(point.mean)).coords,
            covariance: self.rotation * point.covariance * self.rotation.transpose(),
        }
    }
}
