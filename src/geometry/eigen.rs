//! The eigen-decomposition of a symmetric 3 × 3 matrix (the plane fits of
//! beam pooling, docs/math.md §5.5: two for nearly every beam of a scan).
//!
//! \[DESIGN\] The smallest eigenvalue in closed form (the trigonometric
//! solution of the characteristic cubic), its eigenvector as the largest
//! cross product of two rows of `A − λI`, and the other two from the 2 × 2
//! block of `A` on the plane normal to it, which one Jacobi rotation
//! diagonalises exactly. That is accurate to the rounding when the smallest
//! eigenvalue stands clear of the others (a plane of hits: 10⁻⁴ of the
//! largest, its two in-plane spreads free to be equal). Otherwise (a line of
//! points, a ball) cyclic Jacobi rotations on the whole matrix, which keep
//! every eigenvalue and vector to the rounding whatever the spectrum.
//! nalgebra's `symmetric_eigen` is written for any size and cost three times
//! as much on the plane fits.

use super::{Matrix3, Vector3};

/// Sweeps before giving up (three or four reach convergence; a matrix with
/// NaN or infinite entries never does and stops here).
const MAX_SWEEPS: usize = 12;

/// The smallest eigenvalue's gap to the next, relative to the matrix's
/// size, below which the closed form hands over to Jacobi: its eigenvector
/// is then good to the rounding over this ratio.
const CLEAR_GAP: f64 = 1e-2;

/// The eigenvalues of the symmetric `m` (its upper triangle is read) and
/// its unit eigenvectors as the columns of the matrix, in matching order
/// (unsorted): `m · v_i = λ_i v_i` to the rounding of `m`'s entries.
pub fn symmetric_eigen(m: &Matrix3) -> (Vector3, Matrix3) {
    let m = Matrix3::from_fn(|i, j| m[(i.min(j), i.max(j))]);
    closed_form(&m).unwrap_or_else(|| jacobi(&m))
}

/// The decomposition through the smallest eigenvalue in closed form, if it
/// stands [`CLEAR_GAP`] clear of the others; columns: its eigenvector,
/// then the other two.
fn closed_form(m: &Matrix3) -> Option<(Vector3, Matrix3)> {
    let off = m[(0, 1)].powi(2) + m[(0, 2)].powi(2) + m[(1, 2)].powi(2);
    let q = m.trace() / 3.0;
    let deviation = (0..3).map(|i| (m[(i, i)] - q).powi(2)).sum::<f64>() + 2.0 * off;
    // The spread of the eigenvalues about their mean: p = √(Σ(λ − q)²/6).
    let p = (deviation / 6.0).sqrt();
    let size = m.norm();
    if p.is_nan() || p <= 1e-8 * size {
        return None;
    }
    let b = (m - Matrix3::identity() * q) / p;
    let half_det = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    let smallest = q + 2.0 * p * (half_det.acos() / 3.0 + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let shifted = m - Matrix3::identity() * smallest;
    let rows = [0, 1, 2].map(|i| shifted.row(i).transpose());
    let normal = [(0, 1), (0, 2), (1, 2)]
        .map(|(i, j)| rows[i].cross(&rows[j]))
        .into_iter()
        .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))?
        .try_normalize(0.0)?;
    // An orthonormal pair across the normal, from the axis least along it.
    let least = (0..3)
        .min_by(|&i, &j| normal[i].abs().total_cmp(&normal[j].abs()))
        .unwrap_or(0);
    let u = normal.cross(&Vector3::ith(least, 1.0)).normalize();
    let v = normal.cross(&u);
    let mu = m * u;
    let (muu, muv, mvv) = (mu.dot(&u), mu.dot(&v), (m * v).dot(&v));
    let (t, c, s) = rotation(muu, muv, mvv);
    let values = Vector3::new((m * normal).dot(&normal), muu - t * muv, mvv + t * muv);
    if values[1].min(values[2]) - values[0] < CLEAR_GAP * size {
        return None;
    }
    let vectors = Matrix3::from_columns(&[normal, u * c - v * s, u * s + v * c]);
    Some((values, vectors))
}

/// The Jacobi rotation that zeroes `a_pq` of the symmetric block
/// `[[a_pp, a_pq], [a_pq, a_qq]]`: `(t, c, s)` with `t = tan θ` and
/// `tan 2θ = 2 a_pq / (a_qq − a_pp)`, through the smaller root (stable);
/// the block's diagonal becomes `(a_pp − t a_pq, a_qq + t a_pq)`.
#[inline]
fn rotation(app: f64, apq: f64, aqq: f64) -> (f64, f64, f64) {
    if apq == 0.0 {
        return (0.0, 1.0, 0.0);
    }
    let theta = (aqq - app) / (2.0 * apq);
    let t = if theta.abs() > 1e150 {
        0.5 / theta
    } else {
        theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
    };
    let c = 1.0 / (t * t + 1.0).sqrt();
    (t, c, t * c)
}

/// The decomposition of the symmetric `m` by cyclic Jacobi rotations: each
/// zeroes one off-diagonal entry, and a sweep over the three converges
/// quadratically.
fn jacobi(m: &Matrix3) -> (Vector3, Matrix3) {
    let mut a: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]));
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..MAX_SWEEPS {
        let mut rotated = false;
        for (p, q, r) in [(0, 1, 2), (0, 2, 1), (1, 2, 0)] {
            let apq = a[p][q];
            // Negligible beside both diagonal entries: already zero to the
            // rounding of a rotation (a zero entry is skipped as well).
            let scale = a[p][p].abs() + a[q][q].abs();
            if apq == 0.0 || (scale > 0.0 && apq.abs() <= f64::EPSILON * scale) {
                a[p][q] = 0.0;
                a[q][p] = 0.0;
                continue;
            }
            rotated = true;
            let (t, c, s) = rotation(a[p][p], apq, a[q][q]);
            a[p][p] -= t * apq;
            a[q][q] += t * apq;
            a[p][q] = 0.0;
            a[q][p] = 0.0;
            let (arp, arq) = (a[r][p], a[r][q]);
            a[r][p] = c * arp - s * arq;
            a[p][r] = a[r][p];
            a[r][q] = s * arp + c * arq;
            a[q][r] = a[r][q];
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
        if !rotated {
            break;
        }
    }
    (
        Vector3::new(a[0][0], a[1][1], a[2][2]),
        Matrix3::from_fn(|i, j| v[i][j]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `max_i ‖m v_i − λ_i v_i‖ / ‖m‖` and `‖VᵀV − I‖`.
    fn residuals(m: &Matrix3) -> (f64, f64) {
        let (values, vectors) = symmetric_eigen(m);
        let norm = m.norm().max(f64::MIN_POSITIVE);
        let equation = (0..3)
            .map(|i| (m * vectors.column(i) - vectors.column(i) * values[i]).norm() / norm)
            .fold(0.0, f64::max);
        let orthonormal = (vectors.transpose() * vectors - Matrix3::identity()).norm();
        (equation, orthonormal)
    }

    /// A symmetric matrix with eigenvalues `values` in a random basis.
    fn with_eigenvalues(rng: &mut ChaCha8Rng, values: [f64; 3]) -> Matrix3 {
        let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)).normalize();
        let rotation = nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(axis),
            rng.random_range(0.0..std::f64::consts::PI),
        );
        let r = rotation.matrix();
        r * Matrix3::from_diagonal(&Vector3::from(values)) * r.transpose()
    }

    #[test]
    fn solves_random_and_degenerate_matrices_to_the_rounding() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for case in 0..20_000 {
            let m = match case % 4 {
                0 => {
                    let b = Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0));
                    b + b.transpose()
                }
                // A plane of hits: two spreads of centimetres, one of noise.
                1 => with_eigenvalues(&mut rng, [4e-4, 3.9e-4, 1e-9]),
                // Two equal eigenvalues, and all three equal.
                2 => with_eigenvalues(&mut rng, [1.0, 1.0, -2.0]),
                _ => with_eigenvalues(&mut rng, [3.0, 3.0, 3.0]),
            };
            let (equation, orthonormal) = residuals(&m);
            assert!(
                equation < 1e-13,
                "case {case}: ‖mv − λv‖/‖m‖ = {equation:e}"
            );
            assert!(
                orthonormal < 1e-13,
                "case {case}: ‖VᵀV − I‖ = {orthonormal:e}"
            );
        }
    }

    #[test]
    fn keeps_a_planes_small_eigenvalue_and_its_normal() {
        // A plane's scatter: the smallest eigenvalue to a relative 1e-9,
        // its eigenvector to 1e-9 of the true normal, as nalgebra's.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for _ in 0..2_000 {
            let m = with_eigenvalues(&mut rng, [4e-4, 1e-4, 1e-8]);
            let (values, vectors) = symmetric_eigen(&m);
            let reference = m.symmetric_eigen();
            let min = |v: &Vector3| (0..3).min_by(|&i, &j| v[i].total_cmp(&v[j])).unwrap();
            let (i, j) = (min(&values), min(&reference.eigenvalues));
            assert!((values[i] / reference.eigenvalues[j] - 1.0).abs() < 1e-9);
            let cosine = vectors
                .column(i)
                .dot(&reference.eigenvectors.column(j))
                .abs();
            assert!(1.0 - cosine < 1e-12, "normals {cosine}");
        }
    }

    #[test]
    fn diagonal_zero_and_non_finite_matrices_end() {
        let diagonal = Matrix3::from_diagonal(&Vector3::new(3.0, -1.0, 2.0));
        let (values, _) = symmetric_eigen(&diagonal);
        let mut sorted: Vec<f64> = values.iter().copied().collect();
        sorted.sort_by(f64::total_cmp);
        for (value, expected) in sorted.iter().zip([-1.0, 2.0, 3.0]) {
            assert!((value - expected).abs() < 1e-15, "{values:?}");
        }
        assert!(residuals(&diagonal).0 < 1e-15);
        assert_eq!(symmetric_eigen(&Matrix3::zeros()).0, Vector3::zeros());
        let (values, _) = symmetric_eigen(&Matrix3::from_element(f64::NAN));
        assert!(values.iter().all(|v| v.is_nan()));
    }
}
