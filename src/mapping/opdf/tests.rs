//! The properties docs/math.md §4 requires of the profile.

use super::*;

const DELTA: f64 = 0.01;

#[test]
fn limits_in_front_behind_and_around_the_sensor() {
    let p = OpdfParams::new(DELTA);
    let (r, sigma, sigma_o) = (1.0, 0.01, 0.005);
    assert!(
        (p.extended(-5.0 * sigma_o, r, sigma, sigma_o) - 0.5).abs() < 1e-6,
        "behind the sensor: unknown"
    );
    assert!(
        p.extended(r / 2.0, r, sigma, sigma_o) < 1e-3,
        "between sensor and surface: empty"
    );
    assert!(
        (p.extended(r + 6.0 * sigma, r, sigma, sigma_o) - 0.5).abs() < 1e-6,
        "behind the surface: unknown"
    );
    assert!(
        (p.extended(0.0, r, sigma, sigma_o) - 0.25).abs() < 1e-6,
        "p_ext(0) = 1/4"
    );
    assert!((p.extended(r, r, sigma, 0.0) - (0.5 + p.peak_excess(sigma))).abs() < 1e-12);
    // No-return beam: free up to wherever it is evaluated, unknown behind the sensor.
    assert!(p.extended(0.5, f64::INFINITY, sigma, sigma_o) < 1e-12);
    assert_eq!(p.stored(0.5, r, sigma, sigma_o), 0.02);
}

#[test]
fn peak_sits_at_the_measured_range_and_is_continuous() {
    let p = OpdfParams::new(DELTA);
    for sigma in [0.002, 0.01, 0.03] {
        let r = 0.8;
        let argmax = (0..=20_000)
            .map(|i| 0.6 + i as f64 * 2e-5)
            .max_by(|a, b| p.surface(*a, r, sigma).total_cmp(&p.surface(*b, r, sigma)))
            .unwrap();
        assert!((argmax - r).abs() < 2e-5, "sigma {sigma}: argmax {argmax}");
        let eps = 1e-9;
        assert!((p.surface(r - eps, r, sigma) - p.surface(r + eps, r, sigma)).abs() < 1e-6);
        // Monotone pieces: rising before r, falling after.
        let mut previous = 0.0;
        for i in 0..100 {
            let v = p.surface(r - 0.1 + i as f64 * 1e-3, r, sigma);
            assert!(v >= previous);
            previous = v;
        }
        previous = f64::INFINITY;
        for i in 0..100 {
            let v = p.surface(r + i as f64 * 1e-3, r, sigma);
            assert!(v <= previous + 1e-15);
            previous = v;
        }
    }
}

#[test]
fn peak_height_falls_with_sigma_as_tabulated() {
    // docs/math.md §4.3 table, Δ = 1.
    let p = OpdfParams::new(1.0);
    for (ratio, peak) in [
        (0.5, 0.98),
        (1.0, 0.899),
        (1.5, 0.766),
        (2.0, 0.699),
        (3.0, 0.633),
        (4.0, 0.600),
        (8.0, 0.550),
    ] {
        assert!(
            (0.5 + p.peak_excess(ratio) - peak).abs() < 1e-3,
            "σ/Δ = {ratio}"
        );
    }
    let mut previous = 1.0;
    for i in 1..100 {
        let peak = p.surface(5.0, 5.0, i as f64 * 0.1);
        assert!(peak <= previous);
        previous = peak;
    }
}

/// The exact 1-D first-hit posterior (docs/math.md §4.7), cells x_j = jΔ, π = ½.
fn first_hit_oracle(r: f64, sigma: f64, cells: usize) -> Vec<f64> {
    let pi: f64 = 0.5;
    let weights: Vec<f64> = (0..cells)
        .map(|j| {
            pi * (1.0 - pi).powi(j as i32)
                * (-(r - j as f64 * DELTA).powi(2) / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let total: f64 = weights.iter().sum();
    let mut before = 0.0;
    weights
        .iter()
        .map(|w| {
            let p = w / total + pi * before;
            before += w / total;
            p
        })
        .collect()
}

#[test]
fn agrees_with_the_first_hit_oracle_for_small_sigma() {
    let p = OpdfParams::new(DELTA);
    for ratio in [0.25, 0.5] {
        let sigma = ratio * DELTA;
        let r = 40.0 * DELTA;
        let oracle = first_hit_oracle(r, sigma, 60);
        for (j, o) in oracle.iter().enumerate().take(45) {
            let ours = p.surface(j as f64 * DELTA, r, sigma);
            assert!(
                (ours - o).abs() < 0.15,
                "σ/Δ {ratio}, cell {j}: {ours} vs oracle {o}"
            );
        }
    }
}

#[test]
fn bayesian_fusion_in_log_odds() {
    // Two agreeing views at 0.8 give 0.941 (paper mode); 0.5 is neutral.
    let fused = probability(logit(0.8) + logit(0.8));
    assert!((fused - 0.941).abs() < 1e-3);
    assert!((probability(logit(0.8) + logit(0.5)) - 0.8).abs() < 1e-12);
}
