//! The six-parameter pose (docs/math.md §1.1) and the rotation derivatives (§2.1).

use super::{Isometry3, Matrix3, Vector3, Vector6};
use nalgebra::{Rotation3, Translation3, UnitQuaternion};

/// A rigid pose as translation and fixed-axis roll/pitch/yaw (radians):
/// `p_parent = xyz + Rz(yaw) Ry(pitch) Rx(roll) p_child` (docs/math.md §1.1, URDF `<origin>`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Pose {
    /// Translation in metres.
    pub xyz: Vector3,
    /// Roll, pitch, yaw in radians.
    pub rpy: Vector3,
}

impl Pose {
    /// The identity pose.
    pub fn identity() -> Self {
        Self::default()
    }

    /// A pose from its translation and roll/pitch/yaw.
    pub fn new(xyz: [f64; 3], rpy: [f64; 3]) -> Self {
        Self {
            xyz: Vector3::from(xyz),
            rpy: Vector3::from(rpy),
        }
    }

    /// A pose from the parameter vector `(x, y, z, roll, pitch, yaw)`.
    pub fn from_params(t: &Vector6) -> Self {
        Self {
            xyz: t.fixed_rows::<3>(0).into(),
            rpy: t.fixed_rows::<3>(3).into(),
        }
    }

    /// The note to print when an angle of `rpy` is more than a full turn
    /// (2π): degrees written where radians are read, most likely. `what`
    /// names where the pose was written.
    pub fn degrees_note(&self, what: &str) -> Option<String> {
        let [roll, pitch, yaw] = [self.rpy.x, self.rpy.y, self.rpy.z];
        self.rpy
            .iter()
            .any(|a| a.abs() > std::f64::consts::TAU)
            .then(|| {
                let radians = [roll, pitch, yaw].map(|a| format!("{:.4}", a.to_radians()));
                format!(
                    "note: {what} rpy = [{roll}, {pitch}, {yaw}] turns more than once: angles \
                     are radians; if these are degrees, write [{}]",
                    radians.join(", ")
                )
            })
    }

    /// The parameter vector `(x, y, z, roll, pitch, yaw)`.
    pub fn params(&self) -> Vector6 {
        Vector6::new(
            self.xyz.x, self.xyz.y, self.xyz.z, self.rpy.x, self.rpy.y, self.rpy.z,
        )
    }

    /// `R = Rz(yaw) Ry(pitch) Rx(roll)`.
    pub fn rotation(&self) -> Matrix3 {
        rotation_rpy(&self.rpy)
    }

    /// The homogeneous transform `T(t)` as an isometry.
    pub fn to_isometry(&self) -> Isometry3 {
        let rotation = Rotation3::from_matrix_unchecked(self.rotation());
        Isometry3::from_parts(
            Translation3::from(self.xyz),
            UnitQuaternion::from_rotation_matrix(&rotation),
        )
    }

    /// Recovers the parameters of an isometry (docs/math.md §1.1, angle recovery;
    /// singular at pitch = ±π/2, where roll and yaw are not unique but `R` is).
    pub fn from_isometry(iso: &Isometry3) -> Self {
        let r = iso.rotation.to_rotation_matrix().into_inner();
        let yaw = r[(1, 0)].atan2(r[(0, 0)]);
        let pitch = (-r[(2, 0)]).atan2((r[(0, 0)].powi(2) + r[(1, 0)].powi(2)).sqrt());
        let roll = r[(2, 1)].atan2(r[(2, 2)]);
        Self {
            xyz: iso.translation.vector,
            rpy: Vector3::new(roll, pitch, yaw),
        }
    }

    /// True when every parameter is finite.
    pub fn is_finite(&self) -> bool {
        self.xyz
            .iter()
            .chain(self.rpy.iter())
            .all(|v| v.is_finite())
    }
}

/// `R(φ, θ, ψ) = Rz(ψ) Ry(θ) Rx(φ)` for `rpy = (φ, θ, ψ)` (docs/math.md §1.1).
pub fn rotation_rpy(rpy: &Vector3) -> Matrix3 {
    let (sr, cr) = rpy.x.sin_cos();
    let (sp, cp) = rpy.y.sin_cos();
    let (sy, cy) = rpy.z.sin_cos();
    Matrix3::new(
        cy * cp,
        -sy * cr + cy * sp * sr,
        sy * sr + cy * sp * cr,
        sy * cp,
        cy * cr + sy * sp * sr,
        -cy * sr + sy * sp * cr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// `E(φ, θ, ψ) = [ω_φ ω_θ ω_ψ]`, the fixed-frame axes of the three angle rates:
/// `∂(R q)/∂(φ, θ, ψ) = -[R q]× E` (docs/math.md §2.1). `det E = cos θ`.
pub fn rpy_rate_matrix(rpy: &Vector3) -> Matrix3 {
    let (sp, cp) = rpy.y.sin_cos();
    let (sy, cy) = rpy.z.sin_cos();
    Matrix3::new(cy * cp, -sy, 0.0, sy * cp, cy, 0.0, -sp, 0.0, 1.0)
}

/// The skew matrix `[a]×` with `[a]× b = a × b`.
pub fn skew(a: &Vector3) -> Matrix3 {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn random_pose(rng: &mut impl Rng) -> Pose {
        Pose::new(
            [
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ],
            [
                rng.random_range(-3.0..3.0),
                rng.random_range(-1.5..1.5),
                rng.random_range(-3.0..3.0),
            ],
        )
    }

    #[test]
    fn urdf_yaw_quarter_turn_maps_x_to_y() {
        let r = Pose::new([0.0; 3], [0.0, 0.0, std::f64::consts::FRAC_PI_2]).rotation();
        assert!((r * Vector3::x() - Vector3::y()).norm() < 1e-15);
    }

    #[test]
    fn rotation_is_rz_ry_rx() {
        let rpy = Vector3::new(0.3, -0.7, 1.9);
        let expected = Rotation3::from_axis_angle(&Vector3::z_axis(), rpy.z)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), rpy.y)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), rpy.x);
        assert!((rotation_rpy(&rpy) - expected.into_inner()).norm() < 1e-14);
    }

    #[test]
    fn isometry_round_trip_and_inverse() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for _ in 0..200 {
            let pose = random_pose(&mut rng);
            let iso = pose.to_isometry();
            let back = Pose::from_isometry(&iso);
            assert!(
                (back.params() - pose.params()).norm() < 1e-9,
                "{pose:?} vs {back:?}"
            );
            let ident = (iso * iso.inverse()).to_homogeneous() - nalgebra::Matrix4::identity();
            assert!(ident.norm() < 1e-12);
        }
    }

    #[test]
    fn rotation_derivative_identity_matches_finite_differences() {
        // ∂(R q)/∂α = -[R q]× E (docs/math.md §2.1), against central differences.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for _ in 0..100 {
            let pose = random_pose(&mut rng);
            let q = Vector3::new(rng.random_range(-1.0..1.0), 0.4, -0.2);
            let analytic = -skew(&(pose.rotation() * q)) * rpy_rate_matrix(&pose.rpy);
            let h = 1e-6;
            for k in 0..3 {
                let mut plus = pose.rpy;
                let mut minus = pose.rpy;
                plus[k] += h;
                minus[k] -= h;
                let fd = (rotation_rpy(&plus) * q - rotation_rpy(&minus) * q) / (2.0 * h);
                let err = (fd - analytic.column(k)).norm();
                assert!(err < 1e-8 * (1.0 + fd.norm()), "column {k}: {err}");
            }
        }
    }
}
