//! Sigma-point propagation (docs/math.md §3): the paper's symmetric 2n set and the
//! scaled unscented transform, with the per-viewpoint precomputation of §3.6.
//!
//! Sigma points that perturb only pose parameters leave the measurement at its
//! mean, so their chain matrices `M_i` are constant for a viewpoint. With
//! `Δ_i = M_i − M_0` and `X̃ = [X; 1]`:
//! `ŷ = M̄ X̃` with `M̄ = M_0 + Δ̄`, `Δ̄ = W Σ Δ_i`, and
//! `Γ = (W_0c + 6W) d_0 d_0ᵀ + W Σ d_i d_iᵀ + R_0 Γ_c R_0ᵀ`
//! with `d_i = D_i X̃`, `D_i = Δ_i − Δ̄`, `d_0 = −Δ̄ X̃` (the six measurement sigma
//! points collapse into the `d_0` and `Γ_c` terms exactly).
//!
//! \[DESIGN\] Since every `D_i` is constant, the sum is a quadratic form in `X̃`
//! ([`QuadraticCovariance`]), built once per viewpoint: a point then costs six
//! 4x4 quadratic forms whatever the number of sigma points.

use super::chain::{Gaussian3, UncertainChain, UncertainPoint};
use super::quadratic::QuadraticCovariance;
use super::{sqrt_factor, Propagator};
use crate::geometry::{Matrix3, Pose, Vector3};
use nalgebra::{Matrix3x4, Point3, Vector4};

/// Which sigma-point set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SigmaSet {
    /// The paper's set (Julier–Uhlmann, κ = 0): `±√n` columns, weights `1/2n`,
    /// no centre point.
    Paper,
    /// Wan–van der Merwe scaled set: `λ = α²(n + κ) − n`, spread `√(n + λ)`,
    /// centre weights `λ/(n+λ)` (mean) and `λ/(n+λ) + 1 − α² + β` (covariance).
    Scaled {
        /// Spread α of the points about the mean.
        alpha: f64,
        /// Prior-knowledge weight β (2 for a Gaussian).
        beta: f64,
        /// Secondary scaling κ.
        kappa: f64,
    },
}

/// Weights and spread of a set for `n` uncertain dimensions.
#[derive(Clone, Copy, Debug)]
struct Weights {
    spread: f64,
    w: f64,
    w0c: f64,
}

/// The scaled set's β when none is given: 2, optimal for Gaussian inputs
/// (Wan–van der Merwe).
pub const DEFAULT_BETA: f64 = 2.0;

impl SigmaSet {
    /// The scaled set, checked: `10⁻⁴ ≤ α ≤ 10`, `0 ≤ β ≤ 100`, `0 ≤ κ ≤ 100`
    /// (κ ≥ 0 keeps `n + κ > 0` whatever the chain's n). The error names the
    /// parameter and its bounds.
    pub fn scaled(alpha: f64, beta: f64, kappa: f64) -> Result<Self, String> {
        // Below α = 1e-4 the set's weights, ~1/α², cancel in floating
        // point: at 1e-7 the covariance is already off by a tenth.
        for (name, value, low, high) in [
            ("alpha", alpha, 1e-4, 10.0),
            ("beta", beta, 0.0, 100.0),
            ("kappa", kappa, 0.0, 100.0),
        ] {
            if !(value.is_finite() && value >= low && value <= high) {
                return Err(format!(
                    "{name} = {value} must be at least {low} and at most {high}"
                ));
            }
        }
        Ok(SigmaSet::Scaled { alpha, beta, kappa })
    }

    fn weights(self, n: usize) -> Weights {
        let n = n as f64;
        match self {
            SigmaSet::Paper => Weights {
                spread: n.sqrt(),
                w: 1.0 / (2.0 * n),
                w0c: 0.0,
            },
            SigmaSet::Scaled { alpha, beta, kappa } => {
                let lambda = alpha * alpha * (n + kappa) - n;
                Weights {
                    spread: (n + lambda).sqrt(),
                    w: 1.0 / (2.0 * (n + lambda)),
                    w0c: lambda / (n + lambda) + 1.0 - alpha * alpha + beta,
                }
            }
        }
    }
}

/// The non-zero columns of a square root of a pose covariance: the directions
/// the sigma points perturb (zero-variance parameters drop out, §3.5).
fn pose_directions(covariance: &crate::geometry::Matrix6) -> Vec<crate::geometry::Vector6> {
    let root = sqrt_factor(covariance);
    let scale = root.amax();
    root.column_iter()
        .filter(|c| scale > 0.0 && c.amax() > 1e-12 * scale)
        .map(nalgebra::Matrix::into_owned)
        .collect()
}

/// Number of pose sigma directions of a chain (the paper's 18, or 12 when
/// `R_scene = R_world`) plus the point's 3.
pub fn sigma_dimension(chain: &UncertainChain) -> usize {
    chain
        .links
        .iter()
        .map(|l| pose_directions(&l.pose.covariance).len())
        .sum::<usize>()
        + 3
}

/// The chain matrix (3x4) with link `link` at `pose`.
fn chain_matrix(chain: &UncertainChain, link: usize, pose: &Pose) -> Matrix3x4<f64> {
    let iso = chain.evaluate(|i| {
        if i == link {
            *pose
        } else {
            chain.links[i].pose.mean
        }
    });
    iso.to_homogeneous().fixed_view::<3, 4>(0, 0).into_owned()
}

/// The unscented transform with per-viewpoint precomputation.
#[derive(Clone, Debug)]
pub struct UnscentedPropagator {
    mean_matrix: Matrix3x4<f64>,
    rotation: Matrix3,
    quadratic: QuadraticCovariance,
    /// Number of sigma points, measurement ones included.
    pub points: usize,
}

impl UnscentedPropagator {
    /// Builds the pose sigma points' chain matrices for `chain` and folds them
    /// into the per-viewpoint quadratic forms.
    pub fn new(chain: &UncertainChain, set: SigmaSet) -> Self {
        let n = sigma_dimension(chain);
        let weights = set.weights(n);
        let m0 = chain
            .nominal()
            .to_homogeneous()
            .fixed_view::<3, 4>(0, 0)
            .into_owned();
        let mut deltas = Vec::with_capacity(2 * (n - 3));
        for (i, link) in chain.links.iter().enumerate() {
            for column in pose_directions(&link.pose.covariance) {
                for sign in [1.0, -1.0] {
                    let pose = Pose::from_params(
                        &(link.pose.mean.params() + column * (sign * weights.spread)),
                    );
                    deltas.push(chain_matrix(chain, i, &pose) - m0);
                }
            }
        }
        let mean_delta = deltas.iter().fold(Matrix3x4::zeros(), |a, d| a + d) * weights.w;
        let centre_weight = weights.w0c + 6.0 * weights.w;
        let mut quadratic = QuadraticCovariance::default();
        quadratic.add_outer(&mean_delta, centre_weight);
        for delta in &deltas {
            quadratic.add_outer(&(delta - mean_delta), weights.w);
        }
        let quadratic = quadratic.finish();
        let points = 2 * n + usize::from(matches!(set, SigmaSet::Scaled { .. }));
        Self {
            mean_matrix: m0 + mean_delta,
            rotation: m0.fixed_view::<3, 3>(0, 0).into_owned(),
            quadratic,
            points,
        }
    }
}

impl Propagator for UnscentedPropagator {
    fn name(&self) -> &'static str {
        "unscented"
    }

    #[inline]
    fn propagate(&self, point: &UncertainPoint) -> Gaussian3 {
        let x = Vector4::new(point.mean.x, point.mean.y, point.mean.z, 1.0);
        Gaussian3 {
            mean: self.mean_matrix * x,
            covariance: self.quadratic.evaluate(&x)
                + self.rotation * point.covariance * self.rotation.transpose(),
        }
    }
}

/// The textbook unscented transform: every sigma point of the full parameter
/// vector evaluated through the exact chain (trigonometry per point). The
/// reference for [`UnscentedPropagator`].
pub fn unscented_naive(chain: &UncertainChain, point: &UncertainPoint, set: SigmaSet) -> Gaussian3 {
    let n = sigma_dimension(chain);
    let weights = set.weights(n);
    let f = |link: Option<(usize, Pose)>, x: Vector3| -> Vector3 {
        let iso = chain.evaluate(|i| match link {
            Some((j, pose)) if j == i => pose,
            _ => chain.links[i].pose.mean,
        });
        (iso * Point3::from(x)).coords
    };
    let mut outputs = Vec::with_capacity(2 * n);
    for (i, link) in chain.links.iter().enumerate() {
        for column in pose_directions(&link.pose.covariance) {
            for sign in [1.0, -1.0] {
                let pose = Pose::from_params(
                    &(link.pose.mean.params() + column * (sign * weights.spread)),
                );
                outputs.push(f(Some((i, pose)), point.mean));
            }
        }
    }
    let root = sqrt_factor(&point.covariance);
    for column in root.column_iter() {
        for sign in [1.0, -1.0] {
            outputs.push(f(None, point.mean + column * (sign * weights.spread)));
        }
    }
    let centre = f(None, point.mean);
    let w0m = 1.0 - weights.w * outputs.len() as f64;
    let mean = outputs.iter().fold(centre * w0m, |a, y| a + y * weights.w);
    let d0 = centre - mean;
    let covariance = outputs
        .iter()
        .fold(d0 * d0.transpose() * weights.w0c, |a, y| {
            a + (y - mean) * (y - mean).transpose() * weights.w
        });
    Gaussian3 { mean, covariance }
}

#[cfg(test)]
mod tests;
