//! Where Mills' ratio bounds a normal tail below a given probability: a
//! table of thresholds for [`Held`](super::Held)'s skip test, so that a cell
//! raised pays a look-up, not a root-finding.
//!
//! `Φ(−x) ≤ φ(x)/x` for `x > 0`, and `φ(x)/x` falls strictly, so any
//! `t` with `φ(t)/t ≤ s` bounds the tail below `s` for every `x ≥ t`. The
//! table holds such a `t` for the smallest `s` of each eighth of an octave
//! (the f64's exponent and first three mantissa bits): larger than the exact
//! root for every `s` of the bucket, by a few hundredths (a bucket spans 9%
//! of `s`, and the root moves by `Δs/s / (x + 1/x)`).

use std::sync::LazyLock;

/// Mantissa bits that split an octave into buckets.
const SUB_BITS: u32 = 3;
/// Bit position of a bucket's index in an f64.
const SHIFT: u32 = 52 - SUB_BITS;
/// The smallest bucket: `s` from 2^-60 (below it the Chernoff bound's
/// threshold, ~9σ, is beyond every band anyway).
const FIRST: u64 = ((1023 - 60) << SUB_BITS) as u64;
/// Buckets up to `s` = ½ (where no threshold is needed).
const BUCKETS: usize = 59 << SUB_BITS;

/// `t` per bucket (see the module's comment).
static THRESHOLDS: LazyLock<Vec<f64>> = LazyLock::new(|| {
    (0..BUCKETS as u64)
        .map(|i| root_above(f64::from_bits((FIRST + i) << SHIFT)))
        .collect()
});

/// A threshold `t` with `Φ(−x) ≤ s` for every `x ≥ t` (Mills' ratio), for
/// `0 < s < ½`; `+∞` where the table does not reach.
#[inline]
pub(super) fn beyond(s: f64) -> f64 {
    let bucket = (s.to_bits() >> SHIFT).wrapping_sub(FIRST) as usize;
    THRESHOLDS.get(bucket).copied().unwrap_or(f64::INFINITY)
}

/// `ln(φ(x)/x / s)`: ≤ 0 where Mills' ratio bounds the tail below `s`.
fn excess(x: f64, s: f64) -> f64 {
    -0.5 * x * x - (x * (2.0 * std::f64::consts::PI).sqrt()).ln() - s.ln()
}

/// A point at or above the root of [`excess`] with `excess ≤ −10⁻¹²` (a
/// margin far above its rounding): Newton's steps from the Chernoff
/// bound's threshold, which lies above it, each kept only if it keeps
/// that margin; `+∞` if the start does not.
fn root_above(s: f64) -> f64 {
    const MARGIN: f64 = -1e-12;
    let mut x = (2.0 * (0.5 / s).ln()).sqrt();
    if excess(x, s) > MARGIN {
        return f64::INFINITY;
    }
    for _ in 0..30 {
        // excess < 0 and falling: the step moves left, towards the root.
        let next = x - excess(x, s) / (-x - 1.0 / x);
        if !(next > 0.0 && next < x) || excess(next, s) > MARGIN {
            break;
        }
        x = next;
    }
    x
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
    /// log-uniformly over the table's reach, at or above Mills' root for
    /// `s`; where Mills' ratio is the tighter bound (s < 0.1) it is the root
    /// for the smallest `s` of its bucket, to 10⁻⁴ (Newton stops a step
    /// short of the margin).
    #[test]
    fn a_threshold_bounds_the_tail_at_mills_root_of_its_bucket() {
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
    }
}
