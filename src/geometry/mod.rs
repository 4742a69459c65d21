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
