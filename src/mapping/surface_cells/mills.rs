//! Where a normal tail surely falls below a given probability: a table of
//! thresholds for [`Held`](super::Held)'s skip test, so that a cell raised
//! pays a look-up, not a root-finding.
//!
//! Sampford's bound on Mills' ratio (DLMF 7.8.4, in the normal law's
//! scale): `Φ(−x) ≤ φ(x) · 4 / (3x + √(x² + 8))` for `x > −1`, within 1.5%
//! of the tail at x = 1 and tighter as x grows (`φ(x)/x`, the textbook
//! bound, is 52% above it at x = 1). The bound falls strictly for `x ≥ 0`,
//! so a `t` where it is at most `s` bounds the tail below `s` for every
//! `x ≥ t`. The table holds such a `t` for the smallest `s` of each eighth
//! of an octave (the f64's exponent and first three mantissa bits): at or
//! above the exact root for every `s` of the bucket, by a few hundredths (a
//! bucket spans 9% of `s`, and the root moves by about `Δs/s / x`).

use std::sync::LazyLock;

/// Mantissa bits that split an octave into buckets.
const SUB_BITS: u32 = 3;
/// Bit position of a bucket's index in an f64.
const SHIFT: u32 = 52 - SUB_BITS;
/// The smallest bucket: `s` from 2^-60 (below it the threshold, ~9σ, lies
/// beyond every band's ±7σ: nothing is skipped there anyway).
const FIRST: u64 = ((1023 - 60) << SUB_BITS) as u64;
/// Buckets up to `s` = ½ (where no threshold is needed).
const BUCKETS: usize = 59 << SUB_BITS;

/// `t` per bucket (see the module's comment).
static THRESHOLDS: LazyLock<Vec<f64>> = LazyLock::new(|| {
    (0..BUCKETS as u64)
        .map(|i| root_above(f64::from_bits((FIRST + i) << SHIFT)))
        .collect()
});

/// A threshold `t ≥ 0` with `Φ(−x) ≤ s` for every `x ≥ t`, for
/// `0 < s < ½`; `+∞` where the table does not reach.
#[inline]
pub(super) fn beyond(s: f64) -> f64 {
    let bucket = (s.to_bits() >> SHIFT).wrapping_sub(FIRST) as usize;
    THRESHOLDS.get(bucket).copied().unwrap_or(f64::INFINITY)
}

/// `ln(B(x) / s)` for Sampford's bound `B` of `Φ(−x)`: ≤ 0 where it puts
/// the tail at most `s`.
fn excess(x: f64, s: f64) -> f64 {
    let bound = 4.0 / (3.0 * x + (x * x + 8.0).sqrt());
    -0.5 * x * x - (2.0 * std::f64::consts::PI).sqrt().ln() + bound.ln() - s.ln()
}

/// The least `x ≥ 0` (to the bisection's resolution) with `excess ≤ −10⁻¹²`,
/// a margin far above its rounding: `excess` falls strictly, so every
/// larger `x` keeps it.
fn root_above(s: f64) -> f64 {
    const MARGIN: f64 = -1e-12;
    let (mut lo, mut hi) = (0.0, 40.0);
    if excess(hi, s) > MARGIN {
        return f64::INFINITY;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if excess(mid, s) > MARGIN {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::opdf::normal_cdf;
    use rand::{Rng, SeedableRng};

    /// The root of [`excess`] for `s`, by bisection on its sign.
    fn root(s: f64) -> f64 {
        let (mut lo, mut hi) = (1e-3, 40.0);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if excess(mid, s) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi
    }

    /// Every threshold bounds the tail: `Φ(−t) ≤ s` for `s` drawn
    /// log-uniformly over the table's reach, at or above the bound's root
    /// for `s`, and the root for the smallest `s` of its bucket to 10⁻⁶; and
    /// the bound holds the tail within 2% from x = 1 on.
    #[test]
    fn a_threshold_bounds_the_tail_at_the_root_of_its_bucket() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for _ in 0..20_000 {
            let s = 2f64.powf(rng.random_range(-59.9..-1.0001));
            let t = beyond(s);
            assert!(
                normal_cdf(-t) <= s,
                "s {s:e}: Φ(−{t}) = {:e}",
                normal_cdf(-t)
            );
            assert!(
                t >= root(s),
                "s {s:e}: threshold {t} below the root {}",
                root(s)
            );
            let edge = f64::from_bits((s.to_bits() >> SHIFT) << SHIFT);
            if s < 0.1 {
                assert!(
                    t - root(edge) < 1e-4,
                    "s {s:e}: threshold {t}, root {}",
                    root(edge)
                );
            }
        }
        assert_eq!(beyond(1e-30), f64::INFINITY);
        for i in 0..=90 {
            let x = 1.0 + 0.1 * f64::from(i);
            let ratio = (excess(x, 1.0).exp()) / normal_cdf(-x);
            assert!((1.0..1.02).contains(&ratio), "x {x}: bound / tail {ratio}");
        }
    }
}
