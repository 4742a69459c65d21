//! Covariance consistency statistics (docs/math.md §6): NEES, ANEES with its χ²
//! bounds, Mahalanobis coverage, and distances between covariances.

use crate::geometry::{Matrix3, Vector3};
use statrs::distribution::{ChiSquared, ContinuousCDF, StudentsT};

/// Normalised estimation error squared `eᵀ Γ⁻¹ e` (docs/math.md §6.2). A singular
/// `Γ` gets a relative jitter of 1e-12 of its trace; `∞` if still singular.
pub fn nees(error: &Vector3, covariance: &Matrix3) -> f64 {
    let chol = covariance.cholesky().or_else(|| {
        let jitter = covariance.trace().abs().max(f64::MIN_POSITIVE) * 1e-12;
        (covariance + Matrix3::identity() * jitter).cholesky()
    });
    match chol {
        Some(c) => error.dot(&c.solve(error)),
        None => f64::INFINITY,
    }
}

/// The two-sided `level` acceptance region of ANEES for `n` independent
/// `dof`-dimensional errors: `[χ²_{dof·n}((1−level)/2)/n, χ²_{dof·n}((1+level)/2)/n]`.
pub fn anees_bounds(n: usize, dof: usize, level: f64) -> (f64, f64) {
    let n = n.max(1);
    let k = (dof * n) as f64;
    let tail = (1.0 - level) / 2.0;
    (
        chi_square_quantile(k, tail) / n as f64,
        chi_square_quantile(k, 1.0 - tail) / n as f64,
    )
}

/// Where the mean NEES of `n` independent 3-D errors lies against the 95%
/// band honest covariances give it ([`anees_bounds`]): above it the
/// covariances are too small, below it too large (docs/math.md §6.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Consistency {
    /// Above the band.
    OverConfident,
    /// Inside it.
    Consistent,
    /// Below it.
    Conservative,
}

impl Consistency {
    /// The verdict on the mean NEES `mean` of `n` independent points, with
    /// the band it is judged against.
    pub fn of_mean_nees(mean: f64, n: usize) -> (Self, (f64, f64)) {
        let band = anees_bounds(n, 3, 0.95);
        let verdict = if mean > band.1 {
            Self::OverConfident
        } else if mean < band.0 {
            Self::Conservative
        } else {
            Self::Consistent
        };
        (verdict, band)
    }

    /// Its name for people.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::OverConfident => "over-confident",
            Self::Consistent => "consistent",
            Self::Conservative => "conservative",
        }
    }
}

/// The `p` quantile of χ²_k, by bisection on statrs' CDF to 1e-12 relative
/// (statrs' own `inverse_cdf` stops at about 1e-3).
pub fn chi_square_quantile(k: f64, p: f64) -> f64 {
    let chi = ChiSquared::new(k).expect("positive degrees of freedom");
    invert_cdf(|x| chi.cdf(x), p, k.max(1.0), 1e-12)
}

/// The `p ≥ ½` quantile of Student's t with `dof` degrees of freedom (the
/// summaries' 95% intervals), by the same bisection, to full precision.
pub fn student_t_quantile(dof: f64, p: f64) -> f64 {
    let t = StudentsT::new(0.0, 1.0, dof).expect("positive degrees of freedom");
    invert_cdf(|x| t.cdf(x), p, 1e3, 0.0)
}

/// The `x ≥ 0` where the increasing `cdf` reaches `p` (`cdf(0) ≤ p`), to
/// `relative` precision (0: until the bracket is two adjacent floats); the
/// upper end doubles from `start` until it brackets `p`.
fn invert_cdf(cdf: impl Fn(f64) -> f64, p: f64, start: f64, relative: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, start);
    while cdf(hi) < p {
        hi *= 2.0;
    }
    while hi - lo > relative * hi {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if cdf(mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// `P(χ²_dof ≤ k²)`: the expected share of errors inside the k-sigma ellipsoid
/// (0.1987, 0.7385, 0.9707 for dof 3 and k = 1, 2, 3).
pub fn expected_coverage(k: f64, dof: usize) -> f64 {
    ChiSquared::new(dof as f64)
        .expect("positive degrees of freedom")
        .cdf(k * k)
}

/// A consistency verdict over a set of independent errors.
#[derive(Clone, Debug, PartialEq)]
pub struct ConsistencyReport {
    /// Number of errors.
    pub n: usize,
    /// Average NEES.
    pub anees: f64,
    /// Two-sided 95% bounds of ANEES for `n` (dof 3).
    pub bounds: (f64, f64),
    /// Share of errors inside the 1, 2, 3 sigma ellipsoids.
    pub coverage: [f64; 3],
    /// Their expectations for dof 3.
    pub expected: [f64; 3],
}

impl ConsistencyReport {
    /// From predicted covariances and the true errors (truth − predicted mean).
    /// The errors must be independent for the χ² bounds to hold: points of one
    /// viewpoint share its pose error (docs/math.md §6.6).
    pub fn new<'a>(pairs: impl IntoIterator<Item = (Vector3, &'a Matrix3)>) -> Self {
        let mut n = 0usize;
        let mut sum = 0.0;
        let mut inside = [0usize; 3];
        for (error, cov) in pairs {
            let e = nees(&error, cov);
            n += 1;
            sum += e;
            for (k, count) in inside.iter_mut().enumerate() {
                if e <= ((k + 1) * (k + 1)) as f64 {
                    *count += 1;
                }
            }
        }
        let share = |c: usize| {
            if n == 0 {
                f64::NAN
            } else {
                c as f64 / n as f64
            }
        };
        Self {
            n,
            anees: if n == 0 { f64::NAN } else { sum / n as f64 },
            bounds: anees_bounds(n, 3, 0.95),
            coverage: inside.map(share),
            expected: [1.0, 2.0, 3.0].map(|k| expected_coverage(k, 3)),
        }
    }

    /// ANEES inside its 95% bounds.
    pub fn is_consistent(&self) -> bool {
        self.anees >= self.bounds.0 && self.anees <= self.bounds.1
    }
}

/// `‖Γ̂ − Γ_ref‖_F / ‖Γ_ref‖_F`.
pub fn relative_frobenius(predicted: &Matrix3, reference: &Matrix3) -> f64 {
    (predicted - reference).norm() / reference.norm()
}

/// `D_KL(N(μ0, Σ0) ‖ N(μ1, Σ1))` for 3-D Gaussians (docs/math.md §6.4); report it as
/// `kl_divergence(Monte Carlo, predicted)`. `∞` when `Σ1` is singular.
pub fn kl_divergence(mean0: &Vector3, cov0: &Matrix3, mean1: &Vector3, cov1: &Matrix3) -> f64 {
    let Some(chol1) = cov1.cholesky() else {
        return f64::INFINITY;
    };
    let det0 = cov0.determinant();
    if det0 <= 0.0 {
        return f64::INFINITY;
    }
    let trace = chol1.solve(cov0).trace();
    let d = mean1 - mean0;
    0.5 * (trace + d.dot(&chol1.solve(&d)) - 3.0 + (chol1.determinant() / det0).ln())
}

/// Förstner–Moonen distance `sqrt(Σ ln² λ_i)`, `λ_i` the eigenvalues of
/// `B⁻¹ A` (symmetric, affine-invariant; a uniform 10% variance error gives 0.165).
pub fn forstner_distance(a: &Matrix3, b: &Matrix3) -> f64 {
    let Some(chol) = b.cholesky() else {
        return f64::INFINITY;
    };
    // Eigenvalues of L⁻¹ A L⁻ᵀ equal those of B⁻¹ A, and it is symmetric.
    let l_inv = chol.l().try_inverse().unwrap_or_else(Matrix3::zeros);
    let m = l_inv * a * l_inv.transpose();
    let eig = (m + m.transpose()) * 0.5;
    eig.symmetric_eigenvalues()
        .iter()
        .map(|l| l.max(f64::MIN_POSITIVE).ln().powi(2))
        .sum::<f64>()
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anees_bounds_match_the_tabulated_values() {
        // docs/math.md §6.2 table (n = 3).
        for (n, lo, hi) in [
            (25, 2.118, 4.034),
            (50, 2.360, 3.716),
            (100, 2.539, 3.499),
            (1000, 2.850, 3.154),
        ] {
            let (l, h) = anees_bounds(n, 3, 0.95);
            assert!(
                (l - lo).abs() < 1.5e-3 && (h - hi).abs() < 1.5e-3,
                "n {n}: [{l}, {h}]"
            );
        }
        let (l, h) = anees_bounds(1, 3, 0.95);
        assert!((l - 0.216).abs() < 1e-3 && (h - 9.348).abs() < 1e-3);
    }

    #[test]
    fn coverage_expectations_for_three_dof() {
        for (k, p) in [(1.0, 0.1987), (2.0, 0.7385), (3.0, 0.9707)] {
            assert!((expected_coverage(k, 3) - p).abs() < 1e-4);
        }
        assert!((expected_coverage(1.0, 1) - 0.6827).abs() < 1e-4);
    }

    #[test]
    fn distances_behave() {
        let a = Matrix3::new(2.0, 0.3, 0.0, 0.3, 1.0, 0.1, 0.0, 0.1, 0.5);
        assert!(forstner_distance(&a, &a) < 1e-12);
        assert!((forstner_distance(&(a * 1.1), &a) - 3f64.sqrt() * 1.1f64.ln()).abs() < 1e-12);
        assert!(kl_divergence(&Vector3::zeros(), &a, &Vector3::zeros(), &a).abs() < 1e-12);
        assert!(kl_divergence(&Vector3::zeros(), &a, &Vector3::x(), &a) > 0.0);
        assert!((relative_frobenius(&(a * 1.5), &a) - 0.5).abs() < 1e-12);
        assert!(
            (nees(
                &Vector3::new(1.0, 2.0, 0.0),
                &Matrix3::from_diagonal_element(4.0)
            ) - 1.25)
                .abs()
                < 1e-12
        );
    }
}
