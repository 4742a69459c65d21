use super::*;
use rand::{Rng, SeedableRng};

/// A grid of random beams (some bins empty, some with several beams).
fn random_grid(rng: &mut impl Rng) -> LocalGrid {
    let axis = |count| Axis {
        start: -0.2,
        step: 0.01,
        count,
    };
    let ends: Vec<BeamEnd> = (0..400)
        .map(|_| {
            let direction = Vector3::new(
                1.0,
                rng.random_range(-0.2..0.2),
                rng.random_range(-0.2..0.12),
            )
            .normalize();
            if rng.random_bool(0.1) {
                BeamEnd::Miss { direction }
            } else {
                let sigma = rng.random_range(0.001..0.05);
                BeamEnd::Hit {
                    point: direction * rng.random_range(0.2..1.5),
                    covariance: Matrix3::identity() * sigma * sigma,
                }
            }
        })
        .collect();
    LocalGrid::new(
        Vector3::zeros(),
        Matrix3::identity(),
        axis(41),
        axis(33),
        2.0,
        &ends,
        &(Matrix3::identity() * 1e-6),
    )
}

#[test]
fn box_queries_bound_the_beams_they_cover() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let grid = random_grid(&mut rng);
    assert!(grid.beam_count() > 300);
    let dims = [grid.azimuth.count, grid.elevation.count];
    for _ in 0..500 {
        let pick = |rng: &mut rand_chacha::ChaCha8Rng, n: usize| {
            let a = rng.random_range(0..n);
            (a, rng.random_range(a..n))
        };
        let (a, e) = (pick(&mut rng, dims[0]), pick(&mut rng, dims[1]));
        let s = grid.query(a, e);
        let (mut near, mut far, mut origin, mut filled) =
            (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, 0u32);
        for aa in a.0..=a.1 {
            for ee in e.0..=e.1 {
                let (beams, _) = grid.bin_beams(aa, ee);
                filled += u32::from(!beams.is_empty());
                for b in beams {
                    near = near.min(b.band_start(grid.max_range));
                    far = far.max(b.reach(grid.max_range));
                    origin = origin.max(TAIL * b.sigma_origin);
                }
                if let Some(surface) = grid.bin_surface(aa, ee) {
                    near = near.min(surface.band_start(grid.max_range));
                }
            }
        }
        let bins = ((a.1 - a.0 + 1) * (e.1 - e.0 + 1)) as u32;
        assert!(
            s.near <= near && s.far >= far && s.origin >= origin,
            "{s:?} vs {near} {far} {origin}"
        );
        // A superset: at least the bins asked for, and "all filled" only
        // when they are.
        assert!(s.bins >= bins);
        if s.filled == s.bins {
            assert_eq!(filled, bins);
        }
        if a.0 == a.1 && e.0 == e.1 {
            assert_eq!((s.near, s.far, s.bins, s.filled), (near, far, 1, filled));
        }
    }
}

#[test]
fn beams_land_in_their_bins_in_input_order() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let grid = random_grid(&mut rng);
    let mut total = 0;
    for a in 0..grid.azimuth.count {
        for e in 0..grid.elevation.count {
            let (beams, inverse) = grid.bin_beams(a, e);
            total += beams.len();
            for (b, inv) in beams.iter().zip(inverse) {
                assert_eq!(grid.bin_of(&(b.direction * 0.5)), Some((a, e)));
                assert!((b.direction.component_mul(inv) - Vector3::repeat(1.0)).norm() < 1e-12);
            }
        }
    }
    assert_eq!(total, grid.beam_count());
}

#[test]
fn a_bins_surface_is_the_nearest_the_surface_comes_within_it() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let grid = random_grid(&mut rng);
    let (na, ne) = (grid.azimuth.count, grid.elevation.count);
    let nearest = |a: usize, e: usize| {
        grid.bin_beams(a, e)
            .0
            .iter()
            .map(|b| b.range)
            .reduce(f64::min)
    };
    let mut pulled = 0;
    for a in 0..na {
        for e in 0..ne {
            let Some(own) = nearest(a, e) else {
                assert!(grid.bin_surface(a, e).is_none());
                continue;
            };
            let mut expected = own;
            for x in a.saturating_sub(1)..=(a + 1).min(na - 1) {
                for y in e.saturating_sub(1)..=(e + 1).min(ne - 1) {
                    if let Some(other) = nearest(x, y) {
                        // Half-way to a nearer neighbour; all the way when the
                        // bin's own beams had no return.
                        let bound = if own.is_finite() {
                            0.5 * (own + other)
                        } else {
                            other
                        };
                        expected = expected.min(bound);
                    }
                }
            }
            let surface = grid.bin_surface(a, e).expect("a filled bin has a surface");
            assert_eq!(surface.range, expected, "bin ({a}, {e})");
            let beams = grid.bin_beams(a, e).0;
            assert!(beams.iter().all(|b| surface.sigma >= b.sigma));
            pulled += usize::from(expected < own);
        }
    }
    assert!(pulled > 10, "{pulled}");
}

#[test]
fn the_query_level_is_the_first_with_at_most_two_tiles_a_side() {
    for span in 1..100_000usize {
        let mut level = 0;
        while (span >> level) > 2 {
            level += 1;
        }
        assert_eq!(super::query_level(span), level, "span {span}");
    }
}
