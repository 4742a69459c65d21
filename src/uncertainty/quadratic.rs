//! A covariance that is a quadratic form in the homogeneous point
//! `X̃ = [X; 1]`: `Γ(X)_ab = X̃ᵀ Q_ab X̃` (six 4x4 matrices, `a <= b`).
//!
//! \[DESIGN\] Both the first-order and the sigma-point covariances of a chain
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
    ///
    /// Each entry is `x · (Q_ab x)` with the operations, and so the bits, of
    /// nalgebra's `x.dot(&(q * x))`: `Q x` accumulated column by column,
    /// `y = Q_{·0} x_0`, then `y = Q_{·j} x_j + y`; the dot product as
    /// `(x_0 y_0 + x_2 y_2) + (x_1 y_1 + x_3 y_3)`. Written out over plain
    /// arrays so that the four rows go through the vector unit together, four
    /// lanes wide where the CPU has AVX (separate multiplies and adds, never
    /// fused: the same roundings on either path).
    #[inline]
    pub fn evaluate(&self, x: &Vector4<f64>) -> Matrix3 {
        let x = [x[0], x[1], x[2], x[3]];
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX, checked just above.
            return unsafe { self.evaluate_avx(&x) };
        }
        self.evaluate_at(&x)
    }

    /// [`QuadraticCovariance::evaluate`] compiled for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn evaluate_avx(&self, x: &[f64; 4]) -> Matrix3 {
        self.evaluate_at(x)
    }

    #[inline(always)]
    fn evaluate_at(&self, x: &[f64; 4]) -> Matrix3 {
        let mut entries = [0.0; 6];
        for (q, entry) in self.q.iter().zip(&mut entries) {
            let q = q.as_slice();
            let mut y = [0.0; 4];
            for (r, y) in y.iter_mut().enumerate() {
                *y = q[r] * x[0];
            }
            for (j, &xj) in x.iter().enumerate().skip(1) {
                for (r, y) in y.iter_mut().enumerate() {
                    *y += q[4 * j + r] * xj;
                }
            }
            *entry = (x[0] * y[0] + x[2] * y[2]) + (x[1] * y[1] + x[3] * y[3]);
        }
        let mut cov = Matrix3::zeros();
        for (&(a, b), &v) in PAIRS.iter().zip(&entries) {
            cov[(a, b)] = v;
            cov[(b, a)] = v;
        }
        cov
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The written-out evaluation is nalgebra's `x.dot(&(q * x))` bit for
    /// bit, so the maps do not move.
    #[test]
    fn evaluate_matches_nalgebra_bit_for_bit() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut draw = |scale: f64| rng.random_range(-1.0..1.0) * scale;
        for _ in 0..2_000 {
            let mut quadratic = QuadraticCovariance::default();
            for q in &mut quadratic.q {
                *q = Matrix4::from_fn(|_, _| draw(1e-4));
            }
            let quadratic = quadratic.finish();
            let x = Vector4::new(draw(3.0), draw(3.0), draw(3.0), 1.0);
            // The dispatched path (AVX where the CPU has it) and the plain one.
            let paths = [
                quadratic.evaluate(&x),
                quadratic.evaluate_at(&[x[0], x[1], x[2], x[3]]),
            ];
            for got in paths {
                for (&(a, b), q) in PAIRS.iter().zip(&quadratic.q) {
                    let want = x.dot(&(q * x));
                    assert_eq!(got[(a, b)].to_bits(), want.to_bits(), "({a}, {b})");
                    assert_eq!(got[(b, a)].to_bits(), want.to_bits(), "({b}, {a})");
                }
            }
        }
    }
}
