//! Poses and rigid transforms in the paper's parametrisation (docs/math.md §1–2).
//!
//! A pose is six numbers `(x, y, z, roll, pitch, yaw)` with
//! `R = Rz(yaw) Ry(pitch) Rx(roll)` (the URDF fixed-axis convention). Angles are
//! perturbed additively everywhere in sigmap. A transform named `a_from_b` maps
//! b-coordinates to a-coordinates.

mod eigen;
mod pose;

pub use eigen::symmetric_eigen;
pub use pose::{rotation_rpy, rpy_rate_matrix, skew, Pose};

/// 3-vectors, points and matrices of the library (nalgebra, f64).
pub type Vector3 = nalgebra::Vector3<f64>;
/// A point in 3-D.
pub type Point3 = nalgebra::Point3<f64>;
/// A 3x3 matrix.
pub type Matrix3 = nalgebra::Matrix3<f64>;
/// Six pose parameters `(x, y, z, roll, pitch, yaw)`.
pub type Vector6 = nalgebra::Vector6<f64>;
/// A 6x6 matrix (pose covariances).
pub type Matrix6 = nalgebra::Matrix6<f64>;
/// A rigid transform.
pub type Isometry3 = nalgebra::Isometry3<f64>;

/// `⌊v⌋` as an integer, as `v.floor() as i64` gives it (saturating, NaN → 0),
/// without the libm call `f64::floor` is on baseline x86-64 (hot in the
/// grid's bin lookups).
#[inline]
pub fn floor(v: f64) -> i64 {
    let truncated = v as i64;
    truncated.saturating_sub(i64::from((truncated as f64) > v))
}

/// The larger of `a` and `b`, which are never NaN: `f64::max` without its
/// NaN handling, one select where `f64::max` takes five instructions (hot in
/// the grid's per-bin aggregates). On a tie it gives `a`; `f64::max` may then
/// differ only in the sign of a zero.
#[inline]
pub fn larger(a: f64, b: f64) -> f64 {
    debug_assert!(!a.is_nan() && !b.is_nan(), "larger({a}, {b})");
    if b > a {
        b
    } else {
        a
    }
}

/// The smaller of `a` and `b`, which are never NaN ([`larger`]'s mirror).
#[inline]
pub fn smaller(a: f64, b: f64) -> f64 {
    debug_assert!(!a.is_nan() && !b.is_nan(), "smaller({a}, {b})");
    if b < a {
        b
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn floor_is_the_library_floor_everywhere() {
        let specials = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            -1.0,
            1.0 - f64::EPSILON,
            -1e-300,
            2.5e15 + 0.5,
            -(2f64.powi(53)) - 2.0,
            9.3e18,
            -9.3e18,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let random = (0..100_000).map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2e4
        });
        for v in specials.into_iter().chain(random) {
            assert_eq!(super::floor(v), v.floor() as i64, "{v}");
        }
    }

    #[test]
    fn larger_and_smaller_are_the_library_max_and_min_without_nan() {
        let specials = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e-300,
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut random = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            // Few distinct values, so that ties come up.
            (state % 9) as f64 - 4.0
        };
        let pairs = specials
            .iter()
            .flat_map(|&a| specials.iter().map(move |&b| (a, b)))
            .chain((0..10_000).map(|_| (random(), random())));
        for (a, b) in pairs {
            let (max, min) = (super::larger(a, b), super::smaller(a, b));
            // The same value; the same bits unless both are zeros.
            assert_eq!(max, a.max(b), "larger({a}, {b})");
            assert_eq!(min, a.min(b), "smaller({a}, {b})");
            if a != 0.0 || b != 0.0 {
                assert_eq!(max.to_bits(), a.max(b).to_bits(), "larger({a}, {b})");
                assert_eq!(min.to_bits(), a.min(b).to_bits(), "smaller({a}, {b})");
            }
        }
    }
}
