//! First-order propagation: the analytic Jacobian of the chain (docs/math.md §2.2,
//! generalised to any number of links, any of them inverted).
//!
//! With `A_i = T_1 ··· T_{i−1}` (rotation `P_i`, translation `a_i`) and the
//! output point `X_out`, link `i` contributes the 3x6 block
//! `J_i = [B_p  σ [X_out − c_i]× B_α]`:
//! - `T(t)`: `B_p = P_i`, `B_α = P_i E(α_i)`, `σ = −1`, `c_i = P_i p_i + a_i`;
//! - `T(t)⁻¹`: `B_p = −P_i R_iᵀ`, `B_α = P_i R_iᵀ E(α_i)`, `σ = +1`, `c_i = a_i`;
//!
//! and the point the block `P_{k+1}` (the whole chain's rotation). With
//! `K_i = blkdiag(B_p, B_α) Γ_i blkdiag(B_p, B_α)ᵀ` and `w = X_out − c_i`,
//! `J_i Γ_i J_iᵀ = K_pp + σ(K_pα [w]×ᵀ + [w]× K_αp) + [w]× K_αα [w]×ᵀ`.
//! `w = G_i X̃` is affine in the measured point, so the pose part of `Γ_s` is a
//! quadratic form in `X̃` ([`QuadraticCovariance`]) that [`JacobianPropagator`]
//! builds once per viewpoint.

use super::chain::{Gaussian3, UncertainChain, UncertainPoint};
use super::quadratic::QuadraticCovariance;
use super::Propagator;
use crate::geometry::{rpy_rate_matrix, skew, Isometry3, Matrix3, Matrix6, Vector3};
use nalgebra::{DMatrix, Point3, Vector4};

/// The per-viewpoint constants of one link.
#[derive(Clone, Debug)]
struct LinkBlock {
    b_p: Matrix3,
    b_alpha: Matrix3,
    sign: f64,
    centre: Vector3,
    k: Matrix6,
}

fn link_blocks(chain: &UncertainChain) -> (Vec<LinkBlock>, Isometry3) {
    let mut prefix = Isometry3::identity();
    let mut blocks = Vec::with_capacity(chain.links.len());
    for link in &chain.links {
        let p = prefix.rotation.to_rotation_matrix().into_inner();
        let a = prefix.translation.vector;
        let r = link.pose.mean.rotation();
        let e = rpy_rate_matrix(&link.pose.mean.rpy);
        let (b_p, b_alpha, sign, centre) = if link.inverse {
            (-p * r.transpose(), p * r.transpose() * e, 1.0, a)
        } else {
            (p, p * e, -1.0, p * link.pose.mean.xyz + a)
        };
        let mut b = Matrix6::zeros();
        b.fixed_view_mut::<3, 3>(0, 0).copy_from(&b_p);
        b.fixed_view_mut::<3, 3>(3, 3).copy_from(&b_alpha);
        blocks.push(LinkBlock {
            b_p,
            b_alpha,
            sign,
            centre,
            k: b * link.pose.covariance * b.transpose(),
        });
        prefix *= link.transform(&link.pose.mean);
    }
    (blocks, prefix)
}

/// `f(mean)` and the full 3 x (6k+3) Jacobian at the mean, parameters ordered
/// link by link `(x, y, z, roll, pitch, yaw)`, then the point.
pub fn chain_jacobian(chain: &UncertainChain, point: &Vector3) -> (Vector3, DMatrix<f64>) {
    let (blocks, nominal) = link_blocks(chain);
    let out = (nominal * Point3::from(*point)).coords;
    let mut jac = DMatrix::zeros(3, chain.parameter_count());
    for (i, block) in blocks.iter().enumerate() {
        let w = skew(&(out - block.centre));
        jac.fixed_view_mut::<3, 3>(0, 6 * i).copy_from(&block.b_p);
        jac.fixed_view_mut::<3, 3>(0, 6 * i + 3)
            .copy_from(&(w * block.b_alpha * block.sign));
    }
    let n = 6 * blocks.len();
    jac.fixed_view_mut::<3, 3>(0, n)
        .copy_from(&nominal.rotation.to_rotation_matrix().into_inner());
    (out, jac)
}

/// First-order propagation by forming the whole Jacobian and `J Γ Jᵀ` (the
/// reference for [`JacobianPropagator`]; no per-viewpoint reuse).
pub fn jacobian_naive(chain: &UncertainChain, point: &UncertainPoint) -> Gaussian3 {
    let (mean, jac) = chain_jacobian(chain, &point.mean);
    let n = chain.parameter_count();
    let mut gamma = DMatrix::zeros(n, n);
    for (i, link) in chain.links.iter().enumerate() {
        gamma
            .view_mut((6 * i, 6 * i), (6, 6))
            .copy_from(&link.pose.covariance);
    }
    gamma
        .view_mut((n - 3, n - 3), (3, 3))
        .copy_from(&point.covariance);
    let cov = &jac * gamma * jac.transpose();
    Gaussian3 {
        mean,
        covariance: Matrix3::from_fn(|i, j| cov[(i, j)]),
    }
}

/// First-order propagation with the pose part of `Γ_s` built once per viewpoint.
#[derive(Clone, Debug)]
pub struct JacobianPropagator {
    nominal: Isometry3,
    rotation: Matrix3,
    pose_part: QuadraticCovariance,
}

impl JacobianPropagator {
    /// Precomputes the chain's quadratic form; exact links drop out.
    pub fn new(chain: &UncertainChain) -> Self {
        let (blocks, nominal) = link_blocks(chain);
        let m0 = nominal.to_homogeneous();
        let mut pose_part = QuadraticCovariance::default();
        for (b, _) in blocks
            .iter()
            .zip(&chain.links)
            .filter(|(_, link)| !link.pose.is_exact())
        {
            // w = G X̃ with G = [R_0 | t_0 − c]: [w]× = Σ_c X̃_c [g_c]×.
            let columns: [Matrix3; 4] = std::array::from_fn(|c| {
                let g = if c < 3 {
                    m0.fixed_view::<3, 1>(0, c).into_owned()
                } else {
                    m0.fixed_view::<3, 1>(0, 3) - b.centre
                };
                skew(&g)
            });
            let k_pp = b.k.fixed_view::<3, 3>(0, 0).into_owned();
            let k_pa = b.k.fixed_view::<3, 3>(0, 3).into_owned();
            let k_aa = b.k.fixed_view::<3, 3>(3, 3).into_owned();
            pose_part.add_term(3, 3, &k_pp);
            for (c, a_c) in columns.iter().enumerate() {
                let cross = k_pa * a_c.transpose();
                pose_part.add_term(c, 3, &((cross + cross.transpose()) * b.sign));
                for (d, a_d) in columns.iter().enumerate() {
                    pose_part.add_term(c, d, &(a_c * k_aa * a_d.transpose()));
                }
            }
        }
        Self {
            nominal,
            rotation: nominal.rotation.to_rotation_matrix().into_inner(),
            pose_part: pose_part.finish(),
        }
    }
}

impl Propagator for JacobianPropagator {
    fn name(&self) -> &'static str {
        "jacobian"
    }

    #[inline]
    fn propagate(&self, point: &UncertainPoint) -> Gaussian3 {
        let x = Vector4::new(point.mean.x, point.mean.y, point.mean.z, 1.0);
        Gaussian3 {
            mean: (self.nominal * Point3::from(point.mean)).coords,
            covariance: self.pose_part.evaluate(&x)
                + self.rotation * point.covariance * self.rotation.transpose(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Pose, Vector6};
    use crate::uncertainty::chain::ChainLink;
    use crate::uncertainty::UncertainPose;
    use rand::{Rng, SeedableRng};

    pub(crate) fn random_chain(rng: &mut impl Rng, links: usize) -> UncertainChain {
        UncertainChain {
            links: (0..links)
                .map(|i| {
                    let a = Matrix6::from_fn(|_, _| rng.random_range(-1.0..1.0)) * 0.01;
                    ChainLink {
                        name: format!("link {i}"),
                        pose: UncertainPose {
                            mean: Pose::new(
                                [
                                    rng.random_range(-1.0..1.0),
                                    rng.random_range(-1.0..1.0),
                                    rng.random_range(-1.0..1.0),
                                ],
                                [
                                    rng.random_range(-3.0..3.0),
                                    rng.random_range(-1.4..1.4),
                                    rng.random_range(-3.0..3.0),
                                ],
                            ),
                            covariance: a * a.transpose(),
                        },
                        inverse: rng.random_bool(0.5),
                    }
                })
                .collect(),
        }
    }

    #[test]
    fn jacobian_matches_central_differences_at_random_chains() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        for trial in 0..100 {
            let chain = random_chain(&mut rng, 1 + trial % 4);
            let x = Vector3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(0.1..3.0),
            );
            let (_, jac) = chain_jacobian(&chain, &x);
            let f = |params: &[f64]| -> Vector3 {
                let iso = chain.evaluate(|i| {
                    Pose::from_params(&Vector6::from_column_slice(&params[6 * i..6 * i + 6]))
                });
                let n = params.len();
                (iso * Point3::new(params[n - 3], params[n - 2], params[n - 1])).coords
            };
            let mut theta: Vec<f64> = chain
                .links
                .iter()
                .flat_map(|l| l.pose.mean.params().iter().copied().collect::<Vec<_>>())
                .collect();
            theta.extend(x.iter());
            let h = 1e-6;
            for k in 0..theta.len() {
                let mut plus = theta.clone();
                let mut minus = theta.clone();
                plus[k] += h;
                minus[k] -= h;
                let fd = (f(&plus) - f(&minus)) / (2.0 * h);
                let col = jac.column(k);
                let err = (fd - col).norm();
                assert!(
                    err <= 1e-7 * fd.norm().max(1.0),
                    "trial {trial} column {k}: {err:e}"
                );
            }
        }
    }

    #[test]
    fn precomputed_equals_full_jacobian() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        for _ in 0..50 {
            let chain = random_chain(&mut rng, 3);
            let propagator = JacobianPropagator::new(&chain);
            let a = nalgebra::Matrix3::from_fn(|_, _| rng.random_range(-0.01..0.01));
            let point = UncertainPoint {
                mean: Vector3::new(0.3, -0.2, 1.4),
                covariance: a * a.transpose(),
            };
            let naive = jacobian_naive(&chain, &point);
            let fast = propagator.propagate(&point);
            assert!((naive.mean - fast.mean).norm() < 1e-12);
            assert!((naive.covariance - fast.covariance).norm() <= 1e-10 * naive.covariance.norm());
        }
    }

    #[test]
    fn scan_propagation_fills_the_output_in_parallel_as_in_sequence() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let chain = random_chain(&mut rng, 3);
        let propagator = JacobianPropagator::new(&chain);
        let points: Vec<UncertainPoint> = (0..10_000)
            .map(|i| UncertainPoint {
                mean: Vector3::new(i as f64 * 1e-4, 0.1, 1.0),
                covariance: Matrix3::identity() * 1e-6,
            })
            .collect();
        let mut parallel = vec![Gaussian3::default(); points.len()];
        crate::uncertainty::propagate_scan(&propagator, &points, &mut parallel);
        for (p, g) in points.iter().zip(&parallel) {
            assert_eq!(*g, propagator.propagate(p));
        }
    }

    #[test]
    fn translation_only_chain_is_linear_and_exact() {
        // docs/math.md §2 linear limit: angle variances zero.
        let pose = |xyz, rpy, s: f64| UncertainPose {
            mean: Pose::new(xyz, rpy),
            covariance: Matrix6::from_diagonal(&Vector6::new(
                s * s,
                4.0 * s * s,
                s * s,
                0.0,
                0.0,
                0.0,
            )),
        };
        let chain = UncertainChain::paper(
            pose([0.1, 0.2, 0.0], [0.0, 0.0, 0.3], 0.001),
            pose([0.5, 0.0, 0.4], [0.2, -0.1, 1.0], 0.002),
            pose([0.0, 0.05, 0.02], [0.0, 0.0, 0.0], 0.0005),
        );
        let point = UncertainPoint {
            mean: Vector3::new(0.0, 0.0, 1.0),
            covariance: Matrix3::identity() * 1e-6,
        };
        let rsw = chain.links[0].pose.mean.rotation();
        let rrw = chain.links[1].pose.mean.rotation();
        let rcr = chain.links[2].pose.mean.rotation();
        let tr = |c: &Matrix6| c.fixed_view::<3, 3>(0, 0).into_owned();
        let expected = rsw.transpose() * tr(&chain.links[0].pose.covariance) * rsw
            + rsw.transpose() * tr(&chain.links[1].pose.covariance) * rsw
            + rsw.transpose() * rrw * tr(&chain.links[2].pose.covariance) * rrw.transpose() * rsw
            + rsw.transpose()
                * rrw
                * rcr
                * point.covariance
                * (rsw.transpose() * rrw * rcr).transpose();
        let got = JacobianPropagator::new(&chain).propagate(&point);
        assert!((got.covariance - expected).norm() < 1e-18);
    }
}
