//! Monte Carlo propagation: the reference every other propagator is checked
//! against (docs/math.md §6.1). Every parameter is drawn with the same additive
//! perturbation model the other methods assume.

use super::chain::{Gaussian3, UncertainChain, UncertainPoint};
use super::{sqrt_factor, Propagator};
use crate::geometry::{Matrix3, Matrix6, Pose, Vector3};
use nalgebra::Point3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha12Rng;

/// Draws `samples` outputs of the exact chain with every parameter perturbed.
pub fn monte_carlo_samples(
    chain: &UncertainChain,
    point: &UncertainPoint,
    samples: usize,
    rng: &mut impl Rng,
) -> Vec<Vector3> {
    let roots: Vec<Matrix6> = chain
        .links
        .iter()
        .map(|l| sqrt_factor(&l.pose.covariance))
        .collect();
    let point_root = sqrt_factor(&point.covariance);
    (0..samples)
        .map(|_| {
            let poses: Vec<Pose> = chain
                .links
                .iter()
                .zip(&roots)
                .map(|(link, root)| {
                    let xi = super::standard_normal::<6>(rng);
                    Pose::from_params(&(link.pose.mean.params() + root * xi))
                })
                .collect();
            let x = point.mean + point_root * super::standard_normal::<3>(rng);
            (chain.evaluate(|i| poses[i]) * Point3::from(x)).coords
        })
        .collect()
}

/// Sample mean and unbiased sample covariance.
pub fn sample_moments(samples: &[Vector3]) -> Gaussian3 {
    let n = samples.len() as f64;
    let mean = samples.iter().fold(Vector3::zeros(), |a, s| a + s) / n;
    let covariance = samples.iter().fold(Matrix3::zeros(), |a, s| {
        a + (s - mean) * (s - mean).transpose()
    }) / (n - 1.0);
    Gaussian3 { mean, covariance }
}

/// Monte Carlo with `samples` draws per point. Each point gets its own stream,
/// keyed by the seed and the point's coordinates, so results do not depend on
/// the order or thread in which points are propagated.
#[derive(Clone, Debug)]
pub struct MonteCarloPropagator {
    chain: UncertainChain,
    /// Draws per point.
    pub samples: usize,
    seed: u64,
}

impl MonteCarloPropagator {
    /// Monte Carlo over `chain` with `samples` draws per point (at least 2).
    pub fn new(chain: &UncertainChain, samples: usize, seed: u64) -> Self {
        Self {
            chain: chain.clone(),
            samples: samples.max(2),
            seed,
        }
    }
}

impl Propagator for MonteCarloPropagator {
    fn name(&self) -> &'static str {
        "monte_carlo"
    }

    fn propagate(&self, point: &UncertainPoint) -> Gaussian3 {
        let mut rng = ChaCha12Rng::seed_from_u64(self.seed);
        let key = point
            .mean
            .iter()
            .fold(0u64, |h, v| (h ^ v.to_bits()).wrapping_mul(0x100_0000_01B3));
        rng.set_stream(key);
        sample_moments(&monte_carlo_samples(
            &self.chain,
            point,
            self.samples,
            &mut rng,
        ))
    }
}
