use super::*;
use crate::mapping::chord::TAIL;
use rand::{Rng, SeedableRng};

/// A grid of random beams (some bins empty, some with several beams).
fn random_grid(rng: &mut impl Rng) -> LocalGrid {
    random_grid_in(GridBuffers::default(), rng, 400, [41, 33])
}

/// A random unit direction within the test grids' bins (and a little
/// beyond, in elevation).
fn random_direction(rng: &mut impl Rng) -> Vector3 {
    Vector3::new(
        1.0,
        rng.random_range(-0.2..0.2),
        rng.random_range(-0.2..0.12),
    )
    .normalize()
}

/// `count` random beams on `bins` (azimuth x elevation) in `buffers`.
fn random_grid_in(
    buffers: GridBuffers,
    rng: &mut impl Rng,
    count: usize,
    bins: [usize; 2],
) -> LocalGrid {
    let ends = random_ends(rng, count);
    grid_of_ends(buffers, &ends, bins)
}

/// `count` random beam ends: a tenth without a return, the rest at random
/// ranges with random σ.
fn random_ends(rng: &mut impl Rng, count: usize) -> Vec<BeamEnd> {
    (0..count)
        .map(|_| {
            let direction = random_direction(rng);
            random_end(rng, direction)
        })
        .collect()
}

/// A random beam end along `direction`: a tenth without a return, the rest
/// at a random range with a random σ.
fn random_end(rng: &mut impl Rng, direction: Vector3) -> BeamEnd {
    if rng.random_bool(0.1) {
        BeamEnd::Miss { direction }
    } else {
        let sigma = rng.random_range(0.001..0.05);
        BeamEnd::Hit {
            point: direction * rng.random_range(0.2..1.5),
            covariance: Matrix3::identity() * sigma * sigma,
        }
    }
}

/// The grid of `ends` on `bins` (azimuth x elevation) of 0.01 rad from
/// −0.2 rad, in `buffers`.
fn grid_of_ends(buffers: GridBuffers, ends: &[BeamEnd], bins: [usize; 2]) -> LocalGrid {
    let axis = |count| Axis {
        start: -0.2,
        step: 0.01,
        count,
    };
    let layout = GridLayout {
        origin: Vector3::zeros(),
        scene_from_grid: Matrix3::identity(),
        azimuth: axis(bins[0]),
        elevation: axis(bins[1]),
        max_range: 2.0,
    };
    let ends = (ends.len(), |i| Some(ends[i]));
    LocalGrid::from_ends_in(buffers, layout, None, ends, &(Matrix3::identity() * 1e-6))
}

/// Everything a grid answers, bin by bin and tile by tile.
fn contents(grid: &LocalGrid) -> String {
    let mut out = format!("{:?} {}\n", grid.beams(), grid.reach());
    for a in 0..grid.azimuth.count {
        for e in 0..grid.elevation.count {
            let (beams, inverse) = grid.bin_beams(a, e);
            out += &format!(
                "{a} {e} {beams:?} {inverse:?} {:?} ",
                grid.bin_surface(a, e)
            );
            out += &format!("{:?}\n", grid.bin_summary(a, e));
        }
    }
    for level in 0..grid.levels.len() {
        let dims = grid.levels[level].dims;
        for ta in 0..dims[0] {
            for te in 0..dims[1] {
                out += &format!("{:?}\n", grid.tile_summary(level, ta, te));
            }
        }
    }
    out
}

/// Beams in raster order, one or two a bin (a tenth without a return), on
/// `bins` of [`grid_of_ends`]: the input order that `BinSort` keeps in place.
fn raster_ends(rng: &mut impl Rng, bins: [usize; 2]) -> Vec<BeamEnd> {
    let mut ends = Vec::new();
    for e in 0..bins[1] {
        for a in 0..bins[0] {
            for _ in 0..rng.random_range(1..=2) {
                let az: f64 = -0.2 + (a as f64 + rng.random_range(0.2..0.8)) * 0.01;
                let el: f64 = -0.2 + (e as f64 + rng.random_range(0.2..0.8)) * 0.01;
                let direction = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                ends.push(random_end(rng, direction));
            }
        }
    }
    ends
}

/// Raster-ordered beams stay where they were computed, and a grid's beams
/// become the next grid's input buffer (`LocalGrid::into_buffers`): a chain
/// of grids, each in the last one's memory, is the chain built fresh.
#[test]
fn raster_grids_built_each_in_the_last_ones_memory_are_the_same_grids() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(41);
    let mut buffers = GridBuffers::default();
    for bins in [[30, 20], [41, 33], [25, 18], [41, 33]] {
        let ends = raster_ends(&mut rng, bins);
        let fresh = grid_of_ends(GridBuffers::default(), &ends, bins);
        let reused = grid_of_ends(buffers, &ends, bins);
        assert_eq!(contents(&reused), contents(&fresh), "{bins:?}");
        buffers = reused.into_buffers();
    }
}

#[test]
fn a_grid_built_in_another_grids_memory_is_the_same_grid() {
    // Larger and smaller grids before it, so that every array was longer
    // or shorter than the new one needs.
    for (before, after) in [
        ((900, [60, 50]), (400, [41, 33])),
        ((50, [9, 7]), (400, [41, 33])),
        ((400, [41, 33]), (30, [41, 33])),
    ] {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
        let fresh = random_grid_in(GridBuffers::default(), &mut rng, after.0, after.1);
        let mut other = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let old = random_grid_in(GridBuffers::default(), &mut other, before.0, before.1);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
        let reused = random_grid_in(old.into_buffers(), &mut rng, after.0, after.1);
        assert_eq!(contents(&reused), contents(&fresh));
        assert_eq!(reused.levels.len(), fresh.levels.len());
    }
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
        let mut hit_near = f64::INFINITY;
        for aa in a.0..=a.1 {
            for ee in e.0..=e.1 {
                let (beams, _) = grid.bin_beams(aa, ee);
                filled += u32::from(!beams.is_empty());
                for b in beams {
                    near = near.min(b.band_start(grid.max_range));
                    if b.range.is_finite() {
                        hit_near = hit_near.min(b.band_start(grid.max_range));
                    }
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
            s.near <= near && s.hit_near <= hit_near && s.far >= far && s.origin >= origin,
            "{s:?} vs {near} {hit_near} {far} {origin}"
        );
        // A superset: at least the bins asked for, and "all filled" only
        // when they are.
        assert!(s.bins >= bins);
        if s.filled == s.bins {
            assert_eq!(filled, bins);
        }
        if a.0 == a.1 && e.0 == e.1 {
            assert_eq!(
                (s.near, s.hit_near, s.far, s.bins, s.filled),
                (near, hit_near, far, 1, filled)
            );
        }
    }
    // Each bin's own: a bin whose beams all had no return has no band of
    // a beam with a return (its `near` is the maximum range).
    let mut misses_only = 0;
    for a in 0..dims[0] {
        for e in 0..dims[1] {
            let (beams, _) = grid.bin_beams(a, e);
            let hit_near = beams
                .iter()
                .filter(|b| b.range.is_finite())
                .map(|b| b.band_start(grid.max_range))
                .fold(f64::INFINITY, f64::min);
            misses_only += usize::from(!beams.is_empty() && hit_near == f64::INFINITY);
            assert_eq!(
                grid.query((a, a), (e, e)).hit_near,
                hit_near,
                "bin ({a}, {e})"
            );
        }
    }
    assert!(misses_only > 0, "no bin holds only beams without a return");
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
fn ends_already_in_bin_order_make_the_grid_the_sort_makes() {
    // A scan's beams usually come in bin order, and the grid then keeps them
    // where they are instead of sorting them: both ways must give the same
    // grid. The same ends twice, each bin's ends in the same order: once in
    // bin order (the beams left out scattered among them), once with the
    // last bin's ends moved to the front.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
    // Elevations reach 0.12 rad, the bins 0.05: some ends fall outside.
    let bins = [41, 25];
    let ends = random_ends(&mut rng, 600);
    let probe = grid_of_ends(GridBuffers::default(), &ends, bins);
    let bin = |end: &BeamEnd| {
        let direction = match end {
            BeamEnd::Hit { point, .. } => point.normalize(),
            BeamEnd::Miss { direction } => *direction,
        };
        probe
            .bin_of(&direction)
            .map(|(a, e)| bin_index(probe.azimuth.count, a, e))
    };
    let (mut in_grid, left_out): (Vec<BeamEnd>, Vec<BeamEnd>) =
        ends.iter().partition(|end| bin(end).is_some());
    assert!(!left_out.is_empty(), "some ends must fall outside the bins");
    in_grid.sort_by_key(|end| bin(end));
    let mut in_order = in_grid.clone();
    for end in left_out {
        in_order.insert(rng.random_range(0..=in_order.len()), end);
    }
    let last = bin(in_grid.last().expect("ends in the grid"));
    let (mut out_of_order, first): (Vec<BeamEnd>, Vec<BeamEnd>) =
        in_order.iter().partition(|end| bin(end) == last);
    out_of_order.extend(first);
    let in_order = grid_of_ends(GridBuffers::default(), &in_order, bins);
    let sorted = grid_of_ends(GridBuffers::default(), &out_of_order, bins);
    assert_eq!(in_order.beam_count(), in_grid.len());
    assert_eq!(contents(&in_order), contents(&sorted));
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
    let widest = |a: usize, e: usize| {
        grid.bin_beams(a, e)
            .0
            .iter()
            .map(|b| b.sigma)
            .fold(0.0, f64::max)
    };
    let mut pulled = 0;
    for a in 0..na {
        for e in 0..ne {
            let Some(own) = nearest(a, e) else {
                assert!(grid.bin_surface(a, e).is_none());
                continue;
            };
            let (mut expected, mut sigma) = (own, widest(a, e));
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
                        // σ grows by each neighbour that lowers the range
                        // (in row order), the widest of its beams.
                        if bound < expected {
                            expected = bound;
                            sigma = sigma.max(widest(x, y));
                        }
                    }
                }
            }
            let surface = grid.bin_surface(a, e).expect("a filled bin has a surface");
            assert_eq!(surface.range, expected, "bin ({a}, {e})");
            assert_eq!(surface.sigma, sigma, "bin ({a}, {e})");
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
        assert_eq!(super::pyramid::query_level(span), level, "span {span}");
    }
}

/// Binning from the nominal directions changes nothing: a grid built with
/// [`NominalBins`] (beams turned from their nominal directions by up to a
/// bin, so both the table and the full lookup answer) is the grid built
/// without, in a rotated grid frame.
#[test]
fn nominal_bins_give_the_same_grid() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
    let scene_from_grid = *nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.1).matrix();
    let axis = |count| Axis {
        start: -0.2,
        step: 0.01,
        count,
    };
    let (azimuth, elevation) = (axis(41), axis(33));
    let mut nominal_directions = Vec::new();
    let ends: Vec<BeamEnd> = (0..3000)
        .map(|_| {
            let nominal = random_direction(&mut rng);
            nominal_directions.push(scene_from_grid * nominal);
            let turn = if rng.random_bool(0.5) { 1e-6 } else { 0.01 };
            let in_grid =
                (nominal + Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)) * turn).normalize();
            let direction = scene_from_grid * in_grid;
            if rng.random_bool(0.1) {
                BeamEnd::Miss { direction }
            } else {
                BeamEnd::Hit {
                    point: direction * rng.random_range(0.2..1.5),
                    covariance: Matrix3::identity() * 1e-4,
                }
            }
        })
        .collect();
    let layout = GridLayout {
        origin: Vector3::zeros(),
        scene_from_grid,
        azimuth,
        elevation,
        max_range: 2.0,
    };
    let table = NominalBins::new(
        &nominal_directions,
        scene_from_grid.transpose(),
        azimuth,
        elevation,
    );
    let build = |nominal: Option<&NominalBins<'_>>| {
        let ends = (ends.len(), |i: usize| Some(ends[i]));
        let buffers = GridBuffers::default();
        LocalGrid::from_ends_in(
            buffers,
            layout,
            nominal,
            ends,
            &(Matrix3::identity() * 1e-6),
        )
    };
    let decided = ends
        .iter()
        .enumerate()
        .filter(|(i, end)| {
            let direction = match end {
                BeamEnd::Hit { point, .. } => point.normalize(),
                BeamEnd::Miss { direction } => *direction,
            };
            table
                .bin_near(*i, &(scene_from_grid.transpose() * direction))
                .is_some()
        })
        .count();
    assert!(decided > 1200 && decided < 2500, "decided {decided}");
    assert_eq!(contents(&build(Some(&table))), contents(&build(None)));
}
