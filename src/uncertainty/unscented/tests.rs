use super::*;
use crate::uncertainty::chain::ChainLink;
use crate::uncertainty::jacobian::jacobian_naive;
use crate::uncertainty::monte_carlo::{monte_carlo_samples, sample_moments};
use crate::uncertainty::{JacobianPropagator, UncertainPose};
use rand::{Rng, SeedableRng};

fn diag_pose(xyz: [f64; 3], rpy: [f64; 3], st: f64, sa: f64) -> UncertainPose {
    UncertainPose::from_sigmas(Pose::new(xyz, rpy), [st, st, st, sa, sa, sa])
}

/// The paper's setup: scene registration, arm, hand-eye; σ_t in m, σ_α in rad.
fn paper_chain(st: f64, sa: f64) -> UncertainChain {
    UncertainChain::paper(
        diag_pose([0.1, -0.2, 0.05], [0.02, -0.03, 0.4], st, sa),
        diag_pose([0.6, 0.1, 0.5], [3.0, 0.2, -1.1], st * 2.0, sa * 2.0),
        diag_pose([0.0, 0.07, 0.045], [0.0, 0.0, -1.57], st, sa),
    )
}

fn point() -> UncertainPoint {
    UncertainPoint {
        mean: Vector3::new(0.1, -0.15, 0.8),
        covariance: Matrix3::new(1e-6, 2e-7, 0.0, 2e-7, 1.5e-6, 1e-7, 0.0, 1e-7, 4e-6),
    }
}

#[test]
fn precomputed_equals_naive_for_both_sets() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
    for set in [
        SigmaSet::Paper,
        SigmaSet::Scaled {
            alpha: 0.5,
            beta: 2.0,
            kappa: 0.0,
        },
    ] {
        for _ in 0..20 {
            let chain = paper_chain(rng.random_range(1e-4..5e-3), rng.random_range(1e-3..0.1));
            let p = UncertainPoint {
                mean: Vector3::new(
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.5..0.5),
                    rng.random_range(0.2..2.0),
                ),
                ..point()
            };
            let naive = unscented_naive(&chain, &p, set);
            let fast = UnscentedPropagator::new(&chain, set).propagate(&p);
            assert!((naive.mean - fast.mean).norm() < 1e-12, "{set:?}");
            assert!(
                (naive.covariance - fast.covariance).norm() <= 1e-9 * naive.covariance.norm(),
                "{set:?}"
            );
        }
    }
}

#[test]
fn exact_when_the_chain_is_linear_in_its_uncertain_parameters() {
    // Zero angle variances: X_out is affine in the translations and the point,
    // so the UT must give J Γ Jᵀ to machine precision, whatever n is.
    let chain = paper_chain(0.002, 0.0);
    let ut = UnscentedPropagator::new(&chain, SigmaSet::Paper).propagate(&point());
    let lin = jacobian_naive(&chain, &point());
    assert!((ut.covariance - lin.covariance).norm() <= 1e-12 * lin.covariance.norm());
    assert!((ut.mean - lin.mean).norm() < 1e-14);
    let scaled = UnscentedPropagator::new(
        &chain,
        SigmaSet::Scaled {
            alpha: 1e-3,
            beta: 2.0,
            kappa: 0.0,
        },
    )
    .propagate(&point());
    assert!((scaled.covariance - lin.covariance).norm() <= 1e-8 * lin.covariance.norm());
}

/// The smallest α the scaled set takes still gives the linear chain's
/// covariance (at α = 10⁻⁷, past the bound, its weights have cancelled:
/// the covariance is off by a tenth); a smaller α is refused.
#[test]
fn the_smallest_alpha_taken_is_still_exact_on_a_linear_chain() {
    let chain = paper_chain(0.002, 0.0);
    let lin = jacobian_naive(&chain, &point());
    let set = SigmaSet::scaled(1e-4, 2.0, 0.0).unwrap();
    let ut = UnscentedPropagator::new(&chain, set).propagate(&point());
    let error = (ut.covariance - lin.covariance).norm() / lin.covariance.norm();
    assert!(error <= 1e-9, "relative error {error:e}");
    for alpha in [9.9e-5, 0.0, f64::NAN, 10.5] {
        assert!(SigmaSet::scaled(alpha, 2.0, 0.0).is_err(), "alpha {alpha}");
    }
}

#[test]
fn forty_two_points_or_thirty_when_the_scene_frame_is_exact() {
    let chain = paper_chain(0.001, 0.002);
    assert_eq!(sigma_dimension(&chain), 21);
    assert_eq!(UnscentedPropagator::new(&chain, SigmaSet::Paper).points, 42);
    let mut exact_scene = chain.clone();
    exact_scene.links[0].pose = UncertainPose::exact(Pose::identity());
    assert_eq!(sigma_dimension(&exact_scene), 15);
    assert_eq!(
        UnscentedPropagator::new(&exact_scene, SigmaSet::Paper).points,
        30
    );
    // Zero-variance parameters do not bias the covariance at linear order: the
    // result with R_scene = R_world matches the Jacobian as closely as before.
    let ut = UnscentedPropagator::new(&exact_scene, SigmaSet::Paper).propagate(&point());
    let lin = JacobianPropagator::new(&exact_scene).propagate(&point());
    assert!((ut.covariance - lin.covariance).norm() < 1e-2 * lin.covariance.norm());
}

#[test]
fn agrees_with_the_jacobian_at_realistic_sigmas() {
    // docs/math.md §3.6: below 1° the two differ far below Monte Carlo noise.
    for sa_deg in [0.1f64, 0.5, 1.0] {
        let chain = paper_chain(0.001, sa_deg.to_radians());
        let ut = UnscentedPropagator::new(&chain, SigmaSet::Paper).propagate(&point());
        let lin = JacobianPropagator::new(&chain).propagate(&point());
        let d = (ut.covariance - lin.covariance).norm() / lin.covariance.norm();
        assert!(d < 1e-2, "{sa_deg}°: {d}");
    }
}

/// Monte Carlo reference: N draws, sample mean and covariance.
fn monte_carlo(chain: &UncertainChain, p: &UncertainPoint, n: usize) -> Gaussian3 {
    let mut rng = rand_chacha::ChaCha12Rng::seed_from_u64(99);
    sample_moments(&monte_carlo_samples(chain, p, n, &mut rng))
}

#[test]
fn matches_monte_carlo_within_its_standard_errors() {
    // 1° rotation errors (2° on the arm), N = 200 000: each covariance entry
    // of the Monte Carlo estimate has SE √((Σ_ij² + Σ_ii Σ_jj)/(N−1)) and each
    // mean coordinate √(Σ_ii/N) (docs/math.md §6.5). The UT mean must be within
    // 5 SE; each covariance entry within 5 SE plus 1% of √(Σ_ii Σ_jj), the
    // fourth-order error the paper's wide set (±√21 σ) is allowed below 1°
    // (docs/math.md §3.6). Measured: the set overestimates σ_z² by 2.3% here and by
    // 9% at 2°, while the Jacobian stays within 2.2%: see docs/results.md, "Propagation".
    let chain = paper_chain(0.002, 1f64.to_radians());
    let p = point();
    let n = 200_000;
    let mc = monte_carlo(&chain, &p, n);
    let ut = UnscentedPropagator::new(&chain, SigmaSet::Paper).propagate(&p);
    let nf = n as f64;
    for i in 0..3 {
        let se_mean = (mc.covariance[(i, i)] / nf).sqrt();
        assert!(
            (ut.mean[i] - mc.mean[i]).abs() < 5.0 * se_mean,
            "mean {i}: {} vs {}",
            ut.mean[i],
            mc.mean[i]
        );
        for j in 0..3 {
            let c = &mc.covariance;
            let se = ((c[(i, j)].powi(2) + c[(i, i)] * c[(j, j)]) / (nf - 1.0)).sqrt();
            let diff = (ut.covariance[(i, j)] - c[(i, j)]).abs();
            let allowed = 5.0 * se + 0.01 * (c[(i, i)] * c[(j, j)]).sqrt();
            assert!(
                diff < allowed,
                "cov {i}{j}: {:e} vs {:e} (SE {se:e})",
                ut.covariance[(i, j)],
                c[(i, j)]
            );
        }
    }
}

#[test]
fn mean_tracks_monte_carlo_under_large_rotation_errors() {
    // 5° (10° on the arm): f(mean), the Jacobian's mean, misses the second-order
    // bias; the UT mean stays within 5 SE of the Monte Carlo mean.
    let chain = paper_chain(0.002, 5f64.to_radians());
    let p = point();
    let n = 200_000;
    let mc = monte_carlo(&chain, &p, n);
    let ut = UnscentedPropagator::new(&chain, SigmaSet::Paper).propagate(&p);
    let lin = JacobianPropagator::new(&chain).propagate(&p);
    let mut lin_outside = false;
    for i in 0..3 {
        let se = (mc.covariance[(i, i)] / n as f64).sqrt();
        assert!((ut.mean[i] - mc.mean[i]).abs() < 5.0 * se, "UT mean {i}");
        lin_outside |= (lin.mean[i] - mc.mean[i]).abs() > 5.0 * se;
    }
    assert!(lin_outside, "f(mean) should be biased at 5°");
}

#[test]
fn covariance_is_symmetric_psd() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    for _ in 0..50 {
        let chain = UncertainChain {
            links: (0..3)
                .map(|i| ChainLink {
                    name: i.to_string(),
                    pose: diag_pose(
                        [0.2, 0.1, 0.3],
                        [rng.random_range(-3.0..3.0), 0.3, 1.0],
                        0.003,
                        rng.random_range(0.0..0.2),
                    ),
                    inverse: i == 0,
                })
                .collect(),
        };
        let g = UnscentedPropagator::new(&chain, SigmaSet::Paper).propagate(&point());
        assert!(
            (g.covariance - g.covariance.transpose()).norm()
                < 1e-15 * g.covariance.norm().max(1e-300)
        );
        assert!(g.covariance.symmetric_eigenvalues().min() > 0.0);
    }
}
