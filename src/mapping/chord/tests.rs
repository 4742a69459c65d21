//! The chord probability against a Monte Carlo of the first-hit model, and
//! the ray/box chord against sampling.

use super::*;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// Monte Carlo of the first-hit model along one beam: the true surface lies
/// at λ ~ N(r, σ²); C (the chord [a, b]) is occupied when the surface is
/// inside it, unknown (prior ½, a fair coin) when the surface is in front of
/// it, and free (occupied with probability p_lo) when the beam crossed it.
fn first_hit_mc(r: f64, sigma: f64, a: f64, b: f64, p_lo: f64, rng: &mut impl Rng) -> (f64, f64) {
    let n = 200_000;
    let normal = Normal::new(r, sigma).unwrap();
    let mut occupied = 0usize;
    for _ in 0..n {
        let lambda = normal.sample(rng);
        let p = if lambda < a {
            0.5
        } else if lambda <= b {
            1.0
        } else {
            p_lo
        };
        if rng.random_bool(p) {
            occupied += 1;
        }
    }
    let mean = occupied as f64 / n as f64;
    (mean, (mean * (1.0 - mean) / n as f64).sqrt())
}

#[test]
fn chord_probability_matches_a_monte_carlo_of_the_first_hit_model() {
    let model = CellModel::default();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    for _ in 0..40 {
        let r = rng.random_range(0.2..2.0);
        let sigma = rng.random_range(0.0005..0.03);
        // Chords around the surface: in front, straddling, behind.
        let a = r + rng.random_range(-4.0..3.0) * sigma;
        let b = a + rng.random_range(0.002..0.02);
        let beam = Beam {
            direction: Vector3::z(),
            range: r,
            sigma,
            sigma_origin: 0.0,
        };
        let Some(p) = model.occupancy(&beam, a, b, 10.0) else {
            assert!(a > r + TAIL * sigma);
            continue;
        };
        let (mc, se) = first_hit_mc(r, sigma, a, b, model.p_lo, &mut rng);
        let expected = mc.clamp(model.p_lo, model.p_hi);
        assert!(
            (p - expected).abs() < 5.0 * se + 1e-3,
            "r {r}, σ {sigma}, [{a}, {b}]: model {p}, Monte Carlo {mc} ± {se}"
        );
    }
}

#[test]
fn limits_free_surface_occluded_and_no_return() {
    let model = CellModel::default();
    let beam = Beam {
        direction: Vector3::z(),
        range: 1.0,
        sigma: 0.002,
        sigma_origin: 0.001,
    };
    // Crossed well in front of the surface: free.
    assert_eq!(model.occupancy(&beam, 0.5, 0.51, 2.0), Some(0.02));
    // The surface inside the chord: occupied.
    assert!(model.occupancy(&beam, 0.995, 1.005, 2.0).unwrap() > 0.97);
    // Just behind the surface: the prior.
    assert!((model.occupancy(&beam, 1.007, 1.012, 2.0).unwrap() - 0.5).abs() < 0.01);
    // Wholly behind the band: no information.
    assert_eq!(model.occupancy(&beam, 1.5, 1.51, 2.0), None);
    // Around the origin the step blends towards ½.
    let at_origin = model.occupancy(&beam, 0.0, 0.0, 2.0).unwrap();
    assert!((at_origin - 0.26).abs() < 1e-9, "{at_origin}");
    // A no-return beam clears up to the maximum range, then says nothing.
    let miss = Beam {
        range: f64::INFINITY,
        ..beam
    };
    assert_eq!(model.occupancy(&miss, 1.5, 1.51, 2.0), Some(0.02));
    assert_eq!(model.occupancy(&miss, 2.1, 2.11, 2.0), None);
}

#[test]
fn a_risk_level_keeps_cells_near_the_surface_from_being_called_free() {
    let beam = Beam {
        direction: Vector3::z(),
        range: 1.0,
        sigma: 0.02,
        sigma_origin: 0.0,
    };
    // The chord ends one σ before the surface: P(λ > b) = Φ(1) = 0.84.
    let (a, b) = (0.97, 0.98);
    let off = CellModel::default().occupancy(&beam, a, b, 2.0).unwrap();
    assert!(
        off < 0.5,
        "without a risk level the cell is called free: {off}"
    );
    let strict = CellModel::with_risk(Some(0.05))
        .occupancy(&beam, a, b, 2.0)
        .unwrap();
    assert!(strict > 0.5, "at ε = 0.05 it is not: {strict}");
    let loose = CellModel::with_risk(Some(0.2))
        .occupancy(&beam, a, b, 2.0)
        .unwrap();
    assert_eq!(loose, off, "ε = 0.2 < 1 − Φ(1): free is allowed");
    // Far in front, any reasonable ε still certifies free.
    let far = CellModel::with_risk(Some(1e-6))
        .occupancy(&beam, 0.5, 0.51, 2.0)
        .unwrap();
    assert_eq!(far, 0.02);
}

#[test]
fn ray_box_chords_agree_with_sampling() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut crossings = 0;
    for _ in 0..2000 {
        let origin = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let centre = Vector3::from_fn(|_, _| rng.random_range(-0.3..0.3));
        let half = rng.random_range(0.01..0.2);
        // Aimed near the box, sometimes parallel to a slab.
        let mut direction =
            centre + Vector3::from_fn(|_, _| rng.random_range(-2.0..2.0) * half) - origin;
        if rng.random_bool(0.2) {
            direction[rng.random_range(0..3)] = 0.0;
        }
        let direction = direction.normalize();
        let inverse = direction.map(|c| 1.0 / c);
        let inside = |t: f64| {
            let p = origin + direction * t;
            (p - centre).amax() <= half
        };
        let chord = ray_box(&origin, &inverse, &centre, half);
        // Sample t along the ray.
        let ts: Vec<f64> = (0..4000)
            .map(|i| i as f64 * 1e-3)
            .filter(|t| inside(*t))
            .collect();
        match chord {
            None => assert!(ts.is_empty(), "missed a crossing"),
            Some((a, b)) => {
                crossings += 1;
                assert!(a >= 0.0 && a <= b);
                assert!(inside(a + 1e-9 * (b - a)) && inside(b - 1e-9 * (b - a)));
                if let (Some(lo), Some(hi)) = (ts.first(), ts.last()) {
                    assert!(
                        a <= lo + 1e-12 && hi - 1e-12 <= b,
                        "[{a}, {b}] vs [{lo}, {hi}]"
                    );
                    assert!(
                        lo - a < 1.1e-3 && b - hi < 1.1e-3,
                        "[{a}, {b}] vs [{lo}, {hi}]"
                    );
                }
            }
        }
    }
    assert!(crossings > 500, "{crossings}");
}

#[test]
fn a_viewpoint_calls_a_cell_free_only_for_the_share_it_sees_free() {
    let model = CellModel::default();
    // Nothing seen in front of the surface, no surface inside: the prior.
    assert_eq!(model.view_occupancy(0.0, 0.0), 0.5);
    // All of the cell seen free: as free as the model allows.
    assert_eq!(model.view_occupancy(0.0, 1.0), 0.02);
    // A surface surely inside wins whatever the rest says.
    assert_eq!(model.view_occupancy(1.0, 1.0), 0.98);
    // Half the cell seen free: one surface point uniformly placed in the
    // other half, prior ½ — (1 − F) / (2 − F) = 1/3.
    assert!((model.view_occupancy(0.0, 0.5) - 1.0 / 3.0).abs() < 1e-12);
    // H and F combine as "inside, or else somewhere in the unseen rest".
    let (h, f) = (0.3, 0.8);
    let expected = h + (1.0 - h) * (1.0 - f) / (2.0 - f);
    assert!((model.view_occupancy(h, f) - expected).abs() < 1e-12);
    // The risk level: silent (½) unless at least 1 − ε of the cell is seen.
    let strict = CellModel::with_risk(Some(0.05));
    assert_eq!(strict.view_occupancy(0.0, 0.9), 0.5);
    assert_eq!(
        strict.view_occupancy(0.0, 0.96),
        model.view_occupancy(0.0, 0.96)
    );
    assert_eq!(
        CellModel::with_risk(Some(0.2)).view_occupancy(0.0, 0.9),
        model.view_occupancy(0.0, 0.9)
    );
}

#[test]
fn split_and_free_at_are_the_first_hit_probabilities() {
    let model = CellModel::default();
    let beam = Beam {
        direction: Vector3::z(),
        range: 1.0,
        sigma: 0.01,
        sigma_origin: 0.0,
    };
    for (a, b) in [
        (0.98, 0.99),
        (0.995, 1.005),
        (1.0, 1.02),
        (0.9, 0.95),
        (1.05, 1.2),
    ] {
        let (before, inside, after) = model.split(&beam, a, b, 2.0);
        assert!((before + inside + after - 1.0).abs() < 1e-12);
        assert!((before - normal_cdf((a - 1.0) / 0.01)).abs() < 1e-12);
        assert!((after - normal_cdf((1.0 - b) / 0.01)).abs() < 1e-12);
        // The single-beam chord posterior is built from the same three parts.
        let p = before * 0.5 + inside + after * 0.02;
        if let Some(q) = model.occupancy(&beam, a, b, 2.0) {
            assert!(
                (q - p.clamp(0.02, 0.98)).abs() < 1e-12,
                "{a} {b}: {q} vs {p}"
            );
        }
    }
    // A point is free with the probability the surface lies beyond it...
    assert!((model.free_at(&beam.surface(), 0.99, 2.0) - normal_cdf(1.0)).abs() < 1e-12);
    // ...and not at all when that misses the risk level.
    assert_eq!(
        CellModel::with_risk(Some(0.05)).free_at(&beam.surface(), 0.99, 2.0),
        0.0
    );
    assert!(
        (CellModel::with_risk(Some(0.2)).free_at(&beam.surface(), 0.99, 2.0) - normal_cdf(1.0))
            .abs()
            < 1e-12
    );
    // A no-return beam frees every point within the maximum range.
    let miss = Beam {
        range: f64::INFINITY,
        ..beam
    };
    assert_eq!(model.free_at(&miss.surface(), 1.9, 2.0), 1.0);
    assert_eq!(model.free_at(&miss.surface(), 2.1, 2.0), 0.0);
}

#[test]
fn beyond_is_split_s_last_term_bit_for_bit() {
    // `free_at` evaluates one tail; the map must not move by a bit.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let model = CellModel::default();
    for i in 0..20_000 {
        let sigma = match i % 5 {
            0 => 0.0,
            _ => rng.random_range(1e-5..0.05),
        };
        let beam = Beam {
            direction: Vector3::x(),
            range: rng.random_range(0.1..2.0),
            sigma,
            sigma_origin: 0.0,
        };
        let rho = beam.range + rng.random_range(-9.0..9.0) * sigma.max(1e-3);
        let (_, _, after) = model.split(&beam, rho, rho, 3.0);
        assert_eq!(
            CellModel::beyond(&beam.surface(), rho).to_bits(),
            after.to_bits(),
            "{beam:?} at {rho}"
        );
    }
}
