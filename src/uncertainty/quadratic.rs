//! A covariance that is a quadratic form in the homogeneous point
//! `X̃ = [X; 1]`: `Γ(X)_ab = X̃ᵀ Q_ab X̃` (six 4x4 matrices, `a <= b`).
//!
//! [DESIGN] Both the first-order and the sigma-point covariances of a chain
//! have this form in the measured point (docs/math.md §3.6 for the sigma points;
//! for the Jacobian, its blocks are affine in `X`), so both propagators build
//! `Q` once per viewpoint and each point costs six small quadratic forms.

use crate::geometry::Matrix3;
use nalgebra::{Matrix3x4, Matrix4, Vector4};

/// The six `(a, b)` pairs, `a <= b`, of a symmetric 3x3 matrix.
const PAIRS: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// `Γ(X)_ab = X̃ᵀ Q_ab X̃`.
#[derive(Clone, Debug, PartialEq)]
pub struct QuadraticCovariance {
    q: [Matrix4<f64>; 6],
}

impl Default for QuadraticCovariance {
    fn default() -> Self {
        Self {
            q: [Matrix4::zeros(); 6],
        }
    }
}

impl QuadraticCovariance {
    /// Adds `weight · (D X̃)(D X̃)ᵀ`.
    pub fn add_outer(&mut self, d: &Matrix3x4<f64>, weight: f64) {
        for ((a, b), q) in PAIRS.iter().zip(&mut self.q) {
            *q += d.row(*a).transpose() * d.row(*b) * weight;
        }
    }

    /// Adds `X̃_c X̃_d T` (indices 0–3, 3 the homogeneous 1).
    pub fn add_term(&mut self, c: usize, d: usize, t: &Matrix3) {
        for ((a, b), q) in PAIRS.iter().zip(&mut self.q) {
            q[(c, d)] += t[(*a, *b)];
        }
    }

    /// Symmetrises every `Q_ab` (call once, after the last `add`).
    pub fn finish(mut self) -> Self {
        for q in &mut self.q {
            *q = (*q + q.transpose()) * 0.5;
        }
        self
    }

    /// `Γ(X)` at `X̃`.
    #[inline]
    pub fn evaluate(&self, x: &Vector4<f64>) -> Matrix3 {
        let mut cov = Matrix3::zeros();
        for ((a, b), q) in PAIRS.iter().zip(&self.q) {
            let v = x.dot(&(q * x));
            cov[(*a, *b)] = v;
            cov[(*b, *a)] = v;
        }
        cov
    }
}
