//! Poses and rigid transforms in the paper's parametrisation (docs/math.md §1–2).
//!
//! A pose is six numbers `(x, y, z, roll, pitch, yaw)` with
//! `R = Rz(yaw) Ry(pitch) Rx(roll)` (the URDF fixed-axis convention). Angles are
//! perturbed additively everywhere in sigmap. A transform named `a_from_b` maps
//! b-coordinates to a-coordinates.

mod pose;

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
}
