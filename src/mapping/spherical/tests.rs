use super::*;
use rand::{Rng, SeedableRng};

fn random_grid(rng: &mut impl Rng) -> LocalGrid {
    let axis = |count| Axis {
        start: 0.0,
        step: 0.01,
        count,
    };
    let mut grid = LocalGrid::new(
        Vector3::zeros(),
        Matrix3::identity(),
        axis(37),
        axis(11),
        axis(6),
    );
    let dims = grid.dims;
    for slot in 0..dims[1] * dims[2] {
        if rng.random_bool(0.7) {
            grid.filled[slot] = true;
            for v in &mut grid.values[slot * dims[0]..(slot + 1) * dims[0]] {
                *v = rng.random_range(-3.0..3.0f32);
            }
        }
    }
    grid.build_pyramid();
    grid
}

#[test]
fn box_queries_bound_the_bins_they_cover() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let grid = random_grid(&mut rng);
    let dims = grid.dims;
    for _ in 0..500 {
        let pick = |rng: &mut rand_chacha::ChaCha8Rng, n: usize| {
            let a = rng.random_range(0..n);
            (a, rng.random_range(a..n))
        };
        let (r, a, e) = (
            pick(&mut rng, dims[0]),
            pick(&mut rng, dims[1]),
            pick(&mut rng, dims[2]),
        );
        let s = grid.query(r, a, e);
        let (mut min, mut max, mut known) = (f32::INFINITY, f32::NEG_INFINITY, 0);
        for aa in a.0..=a.1 {
            for ee in e.0..=e.1 {
                for rr in r.0..=r.1 {
                    let i = LocalGrid::flat(&dims, rr, aa, ee);
                    min = min.min(grid.values[i]);
                    max = max.max(grid.values[i]);
                    known += grid.filled[i / dims[0]] as u32;
                }
            }
        }
        assert!(
            s.min <= min && s.max >= max && s.known >= known,
            "{s:?} vs [{min}, {max}] {known}"
        );
        assert!(s.mean >= s.min - 1e-5 && s.mean <= s.max + 1e-5);
        if r.0 == r.1 && a.0 == a.1 && e.0 == e.1 {
            assert_eq!((s.min, s.max), (min, max));
        }
    }
}
