//! Covariance matrices: parsing from files, validation and square roots.

use nalgebra::{DMatrix, SMatrix, SVector, SymmetricEigen};
use rand::Rng;
use rand_distr::StandardNormal;
use serde::Deserialize;

/// A covariance as written in sigmap's files: either `sigma = [..]` (standard
/// deviations of independent parameters) or `covariance = [[..], ..]` (a full
/// symmetric positive semi-definite matrix). Units: metres and radians.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CovarianceSpec {
    /// Standard deviations, one per parameter.
    pub sigma: Option<Vec<f64>>,
    /// A full covariance matrix, row by row.
    pub covariance: Option<Vec<Vec<f64>>>,
}

impl CovarianceSpec {
    /// True when neither form is given.
    pub fn is_empty(&self) -> bool {
        self.sigma.is_none() && self.covariance.is_none()
    }

    /// The `N x N` covariance, validated. Errors say what is wrong in words
    /// that name `what` (for example `"[world_from_robot]"`).
    pub fn to_matrix<const N: usize>(&self, what: &str) -> Result<SMatrix<f64, N, N>, String> {
        match (&self.sigma, &self.covariance) {
            (Some(_), Some(_)) => Err(format!(
                "{what}: give either `sigma` or `covariance`, not both"
            )),
            (None, None) => Ok(SMatrix::zeros()),
            (Some(sigma), None) => {
                if sigma.len() != N {
                    return Err(format!(
                        "{what}: `sigma` needs {N} values, found {}",
                        sigma.len()
                    ));
                }
                let mut m = SMatrix::<f64, N, N>::zeros();
                for (i, s) in sigma.iter().enumerate() {
                    if !s.is_finite() {
                        return Err(format!("{what}: sigma[{i}] is {s}, not a finite number"));
                    }
                    if *s < 0.0 {
                        return Err(format!(
                            "{what}: sigma[{i}] = {s} is negative; standard deviations are >= 0"
                        ));
                    }
                    m[(i, i)] = s * s;
                }
                Ok(m)
            }
            (None, Some(rows)) => {
                if rows.len() != N || rows.iter().any(|r| r.len() != N) {
                    return Err(format!("{what}: `covariance` must be a {N}x{N} matrix"));
                }
                let m = SMatrix::<f64, N, N>::from_fn(|i, j| rows[i][j]);
                check_covariance(&m).map_err(|e| format!("{what}: covariance {e}"))?;
                Ok(m)
            }
        }
    }
}

/// Checks that `m` is a valid covariance: finite, symmetric and positive
/// semi-definite (zero variances are allowed: those parameters are exact).
pub fn check_covariance<const N: usize>(m: &SMatrix<f64, N, N>) -> Result<(), String> {
    if let Some(v) = m.iter().find(|v| !v.is_finite()) {
        return Err(format!("has a non-finite entry ({v})"));
    }
    let scale = m.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let asym = (m - m.transpose())
        .iter()
        .fold(0.0f64, |a, v| a.max(v.abs()));
    if asym > 1e-12 * scale {
        return Err(format!("is not symmetric (largest asymmetry {asym:e})"));
    }
    let eig = SymmetricEigen::new(DMatrix::from_fn(N, N, |i, j| m[(i, j)]));
    let min = eig.eigenvalues.min();
    if min < -1e-12 * scale.max(f64::MIN_POSITIVE) {
        return Err(format!(
            "is not positive semi-definite (smallest eigenvalue {min:e})"
        ));
    }
    Ok(())
}

/// The largest pose standard deviations sigmap takes: 1 m along each
/// translation axis, 0.5 rad about each rotation axis (far past any arm,
/// calibration or registration, and where a first-order chain still means
/// something).
pub const MAX_POSE_SIGMA: [f64; 2] = [1.0, 0.5];

/// Checks each standard deviation of a pose covariance (x, y, z, then the
/// three rotations) against [`MAX_POSE_SIGMA`]: the first one above it, as
/// `sigma[i] = … exceeds 1 m`.
pub fn check_pose_sigmas(covariance: &SMatrix<f64, 6, 6>) -> Result<(), String> {
    for i in 0..6 {
        let (sigma, limit, unit) = match i {
            0..3 => (covariance[(i, i)].sqrt(), MAX_POSE_SIGMA[0], "m"),
            _ => (covariance[(i, i)].sqrt(), MAX_POSE_SIGMA[1], "rad"),
        };
        if sigma.is_nan() || sigma > limit {
            return Err(format!("sigma[{i}] = {sigma:e} exceeds {limit} {unit}"));
        }
    }
    Ok(())
}

/// `N` independent standard normal draws: the one sampler of the truth draw
/// and the Monte Carlo reference, so both perturb parameters alike.
pub fn standard_normal<const N: usize>(rng: &mut impl Rng) -> SVector<f64, N> {
    SVector::from_fn(|_, _| rng.sample(StandardNormal))
}

/// A square root `L` with `L Lᵀ = m` for a valid (possibly singular)
/// covariance: the diagonal root of a diagonal matrix, the lower Cholesky
/// factor of a positive-definite one (the paper's choice for sigma points), and
/// for a singular full matrix the symmetric eigendecomposition, which handles
/// zero-variance directions exactly where Cholesky fails.
pub fn sqrt_factor<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    if m.iter().all(|v| *v == 0.0) {
        return SMatrix::zeros();
    }
    // A diagonal matrix has an exact diagonal root.
    if (0..N).all(|i| (0..N).all(|j| i == j || m[(i, j)] == 0.0)) {
        return SMatrix::from_fn(|i, j| {
            if i == j {
                m[(i, i)].max(0.0).sqrt()
            } else {
                0.0
            }
        });
    }
    if let Some(chol) = m.cholesky() {
        return chol.l();
    }
    let eig = SymmetricEigen::new(DMatrix::from_fn(N, N, |i, j| m[(i, j)]));
    let mut root = eig.eigenvectors;
    for (k, lambda) in eig.eigenvalues.iter().enumerate() {
        let s = lambda.max(0.0).sqrt();
        root.column_mut(k).scale_mut(s);
    }
    SMatrix::from_fn(|i, j| root[(i, j)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    #[test]
    fn sigma_gives_diagonal_and_rejects_bad_values() {
        let spec = CovarianceSpec {
            sigma: Some(vec![0.1, 0.0, 2.0]),
            covariance: None,
        };
        let m: Matrix3<f64> = spec.to_matrix("[x]").unwrap();
        assert!(
            (m - Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.0, 4.0))).norm() < 1e-15
        );
        let neg = CovarianceSpec {
            sigma: Some(vec![0.1, -1.0, 2.0]),
            covariance: None,
        };
        assert!(neg.to_matrix::<3>("[x]").unwrap_err().contains("negative"));
        let nan = CovarianceSpec {
            sigma: Some(vec![0.1, f64::NAN, 2.0]),
            covariance: None,
        };
        assert!(nan.to_matrix::<3>("[x]").unwrap_err().contains("finite"));
    }

    #[test]
    fn full_covariance_must_be_symmetric_psd() {
        let not_psd = CovarianceSpec {
            sigma: None,
            covariance: Some(vec![
                vec![1.0, 2.0, 0.0],
                vec![2.0, 1.0, 0.0],
                vec![0.0, 0.0, 1.0],
            ]),
        };
        assert!(not_psd
            .to_matrix::<3>("[x]")
            .unwrap_err()
            .contains("positive semi-definite"));
        let asym = CovarianceSpec {
            sigma: None,
            covariance: Some(vec![
                vec![1.0, 0.5, 0.0],
                vec![0.0, 1.0, 0.0],
                vec![0.0, 0.0, 1.0],
            ]),
        };
        assert!(asym
            .to_matrix::<3>("[x]")
            .unwrap_err()
            .contains("symmetric"));
    }

    #[test]
    fn sqrt_factor_reproduces_singular_covariance() {
        // Rank 2: perfectly correlated first two parameters.
        let m = Matrix3::new(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.25);
        let l = sqrt_factor(&m);
        assert!((l * l.transpose() - m).norm() < 1e-12);
        // Positive definite: the lower Cholesky factor.
        let pd = Matrix3::new(4.0, 1.0, 0.0, 1.0, 3.0, 0.5, 0.0, 0.5, 2.0);
        let l = sqrt_factor(&pd);
        assert!((l * l.transpose() - pd).norm() < 1e-12);
        assert_eq!(l[(0, 1)], 0.0);
        assert_eq!(l[(1, 2)], 0.0);
    }
}
