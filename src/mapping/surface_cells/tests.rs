use super::*;
use crate::geometry::{Matrix3, Point3};
use crate::mapping::merge::{surface_inside, surface_off_bands};
use crate::mapping::spherical::{Axis, BeamEnd};
use rand::{Rng, SeedableRng};

/// A scanner at `origin` looking down −z (grid x = scene −z) at a tilted,
/// bumpy surface, 40 × 30 bins of 0.5° with `per_bin` beams each; ranges
/// with per-beam σ from 0 to `max_sigma`, every seventh beam without a return.
fn random_grid(seed: u64, origin: Vector3, max_sigma: f64, per_bin: usize) -> LocalGrid {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let scene_from_grid = Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, -1.0, 0.0, 0.0);
    let step = 0.5f64.to_radians();
    let axis = |count: usize| Axis {
        start: -(count as f64) * step / 2.0,
        step,
        count,
    };
    let (azimuth, elevation) = (axis(40), axis(30));
    let mut ends = Vec::new();
    for i in 0..40 {
        for j in 0..30 {
            for _ in 0..per_bin {
                let (az, el) = (azimuth.centre(i), elevation.centre(j));
                let jitter = rng.random_range(-0.4..0.4) * step;
                let grid_dir = Vector3::new(
                    el.cos() * (az + jitter).cos(),
                    el.cos() * (az + jitter).sin(),
                    el.sin(),
                );
                let d = scene_from_grid * grid_dir;
                if (i * 30 + j) % 7 == 0 {
                    ends.push(BeamEnd::Miss { direction: d });
                    continue;
                }
                // The surface z = 0.1 x + 0.02 sin(40 y), plus noise.
                let mut t = 0.0;
                for _ in 0..40 {
                    let p = origin + d * t;
                    let gap = p.z - (0.1 * p.x + 0.02 * (40.0 * p.y).sin());
                    t += gap / (-d.z).max(0.2) * 0.5;
                }
                let sigma = if rng.random_bool(0.1) {
                    0.0
                } else {
                    rng.random_range(0.0..max_sigma)
                };
                t += rng.random_range(-2.0..2.0) * sigma;
                ends.push(BeamEnd::Hit {
                    point: origin + d * t,
                    covariance: Matrix3::identity() * sigma * sigma,
                });
            }
        }
    }
    LocalGrid::new(
        origin,
        scene_from_grid,
        azimuth,
        elevation,
        1.5,
        &ends,
        &(Matrix3::identity() * 1e-8),
    )
}

#[test]
fn the_index_gives_every_cell_the_search_value_bit_for_bit() {
    // Cells of 5 mm to 5 cm (bands from a point to many cells long), with
    // and without a risk level: for every finest cell around the surface,
    // the index (or, absent, the off-band rule) equals the full search of
    // every beam of the cell's solid angle, both capped at p_hi as the
    // merge caps them.
    let mut compared = (0, 0);
    for (seed, resolution, max_sigma) in [(1, 0.005, 0.004), (2, 0.02, 0.006), (3, 0.05, 0.002)] {
        let origin = Vector3::new(0.0013, -0.0021, 0.45);
        let grid = random_grid(seed, origin, max_sigma, 1);
        let geometry = Octree::new(resolution);
        let half = geometry.node_size(DEPTH) * 0.5;
        for model in [CellModel::default(), CellModel::with_risk(Some(0.05))] {
            let index = SurfaceCells::new(&grid, &model, &geometry);
            assert!(!index.is_empty());
            let n = (0.2 / resolution) as i32;
            for i in -n..n {
                for j in -n..n {
                    for k in -(0.06 / resolution) as i32..(0.06 / resolution) as i32 {
                        let p = Point3::new(
                            (i as f64 + 0.5) * resolution,
                            (j as f64 + 0.5) * resolution,
                            (k as f64 + 0.5) * resolution,
                        );
                        let key = geometry.key(&p).unwrap();
                        let centre = geometry.center(&key, DEPTH).coords;
                        let Some(bins) = grid.ball_bins(&centre, half * 3f64.sqrt()) else {
                            continue;
                        };
                        let search = surface_inside(&grid, &model, &centre, half, &bins);
                        let indexed = index
                            .get(&key)
                            .unwrap_or_else(|| surface_off_bands(&grid, &model, &centre, half));
                        assert_eq!(
                            indexed.min(model.p_hi).to_bits(),
                            search.min(model.p_hi).to_bits(),
                            "{centre:?} at {resolution} m: indexed {indexed}, search {search}"
                        );
                        compared.0 += usize::from(search > 0.0);
                        compared.1 += usize::from(search >= model.p_hi);
                    }
                }
            }
        }
    }
    assert!(compared.0 > 2000 && compared.1 > 200, "{compared:?}");
}

#[test]
fn the_index_is_the_same_whatever_the_thread_count() {
    // Ten beams per bin: three parallel chunks of beams, whose cells meet.
    let grid = random_grid(4, Vector3::new(0.0, 0.0, 0.4), 0.01, 10);
    let geometry = Octree::new(0.004);
    let model = CellModel::default();
    let build = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| SurfaceCells::new(&grid, &model, &geometry))
    };
    let (one, two) = (build(1), build(2));
    assert!(one.len() > 1000, "{}", one.len());
    let sorted = |index: &SurfaceCells| {
        let mut cells: Vec<_> = index.cells.raised().collect();
        cells.sort_by_key(|&(at, _)| at);
        cells
    };
    assert_eq!(sorted(&one), sorted(&two));
}
