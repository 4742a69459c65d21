//! The local grid and its merge on a synthetic viewpoint: a scanner 0.5 m
//! above a floor, looking straight down.

use super::*;
use crate::geometry::Point3;
use crate::mapping::chord::CellModel;
use crate::mapping::merge::{cell_occupancy, merge, Cell, MergeOptions, MergeStats};
use crate::mapping::octomap_io::to_ot;
use crate::mapping::octree::{Clamp, Octree};
use crate::mapping::opdf::logit;
use crate::mapping::settings::SampleGate;
use crate::mapping::spherical::spherical;
use crate::uncertainty::RangeModel;
use rand::{Rng, SeedableRng};

const FLOOR: f64 = 0.0123;

fn angles(fov_deg: f64, step_deg: f64) -> Vec<f64> {
    let n = (fov_deg / step_deg).round() as usize + 1;
    (0..n)
        .map(|i| (-fov_deg / 2.0 + i as f64 * step_deg).to_radians())
        .collect()
}

/// Camera z points down the scene's −z.
fn looking_down() -> Matrix3 {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0)
}

fn floor_grid(origin: Vector3, h: &[f64], v: &[f64], sigma: f64) -> LocalGrid {
    plane_grid(origin, h, v, sigma, FLOOR, None)
}

/// A scanner at `origin` looking down at the plane z = `floor`; with `noise`,
/// each measured range is off by a seeded N(0, σ²) draw.
fn plane_grid(
    origin: Vector3,
    h: &[f64],
    v: &[f64],
    sigma: f64,
    floor: f64,
    noise: Option<u64>,
) -> LocalGrid {
    plane_grid_with(origin, h, v, floor, noise, |_, _| sigma)
}

/// [`plane_grid`] with beam `(row i, column j)`'s noise `sigma(i, j)`.
fn plane_grid_with(
    origin: Vector3,
    h: &[f64],
    v: &[f64],
    floor: f64,
    noise: Option<u64>,
    sigma: impl Fn(usize, usize) -> f64,
) -> LocalGrid {
    let rotation = looking_down();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(noise.unwrap_or(0));
    let mut beams = Vec::new();
    for (i, &vv) in v.iter().enumerate() {
        for (j, &hh) in h.iter().enumerate() {
            let sigma = sigma(i, j);
            let d = rotation * Vector3::new(vv.cos() * hh.sin(), vv.sin(), vv.cos() * hh.cos());
            let mut t = (origin.z - floor) / -d.z;
            if noise.is_some() {
                let normal = rand_distr::Normal::new(0.0, sigma).unwrap();
                t += rand_distr::Distribution::sample(&normal, &mut rng);
            }
            beams.push(BeamEnd::Hit {
                point: origin + d * t,
                covariance: Matrix3::identity() * sigma * sigma,
            });
        }
    }
    let raster = Raster {
        horizontal: h,
        vertical: v,
    };
    local_grid(
        &origin,
        &(Matrix3::identity() * 1e-6),
        &rotation,
        raster,
        &beams,
        2.0,
    )
}

/// Asserts that `tree`, `grid` merged with `options`, holds at the finest
/// cell around each of `points` (cells of edge `2 half`) the cell model
/// evaluated there, bit for bit; the number of cells the model informs.
fn assert_merged_as_the_model(
    tree: &Octree,
    grid: &LocalGrid,
    options: &MergeOptions,
    points: impl Iterator<Item = Point3>,
) -> usize {
    let half = tree.node_size(crate::mapping::octree::DEPTH) * 0.5;
    let mut informed = 0;
    for p in points {
        let cell = Cell::of(tree, &tree.key(&p).unwrap());
        let c = cell.centre;
        let brute = grid
            .ball_bins(&c, half * 3f64.sqrt())
            .and_then(|bins| cell_occupancy(grid, &options.model, &cell, &bins))
            .map(|p| logit(p) as f32)
            .filter(|l| l.abs() >= 1e-3)
            .map(|l| options.clamp.apply(l));
        let merged = tree.value_at(&Point3::from(c));
        informed += usize::from(brute.is_some());
        // Bit for bit: the merge's shared corner values and coarse
        // updates are the model evaluated cell by cell.
        assert_eq!(
            merged.map(f32::to_bits),
            brute.map(f32::to_bits),
            "{c:?}: merged {merged:?}, brute {brute:?}"
        );
    }
    informed
}

/// The centres of the cells `(i, j, k)` of edge `edge` in the given ranges.
fn cell_centres(
    edge: f64,
    (x, y, z): (
        std::ops::Range<i32>,
        std::ops::Range<i32>,
        std::ops::Range<i32>,
    ),
) -> impl Iterator<Item = Point3> {
    x.flat_map(move |i| {
        let (y, z) = (y.clone(), z.clone());
        y.flat_map(move |j| {
            z.clone().map(move |k| {
                Point3::new(
                    (i as f64 + 0.5) * edge,
                    (j as f64 + 0.5) * edge,
                    (k as f64 + 0.5) * edge,
                )
            })
        })
    })
}

#[test]
fn free_space_surface_and_occlusion_land_where_they_should() {
    let (h, v) = (angles(40.0, 0.5), angles(30.0, 0.5));
    let grid = floor_grid(Vector3::new(0.0013, 0.0021, 0.5), &h, &v, 0.004);
    let mut tree = Octree::new(0.02);
    let stats = merge(&mut tree, &grid, &MergeOptions::default());
    let at = |x: f64, y: f64, z: f64| tree.value_at(&Point3::new(x, y, z));
    assert!(
        at(0.0, 0.0, 0.25).unwrap() < -2.0 + 1e-3,
        "free between sensor and floor"
    );
    assert!(at(0.05, -0.03, 0.1).unwrap() < -1.0);
    assert!(at(0.0, 0.0, FLOOR).unwrap() > 0.5, "occupied at the floor");
    assert!(at(0.0, 0.0, -0.08).is_none(), "unknown behind the floor");
    assert!(
        at(0.5, 0.0, 0.25).is_none(),
        "unknown outside the field of view"
    );
    assert!(at(0.0, 0.0, 0.6).is_none(), "unknown behind the sensor");
    assert!(
        stats.coarse_updates > 0 && stats.fine_updates > 0,
        "{stats:?}"
    );
    // Far fewer updates than finest cells in the frustum (~0.36 x 0.27 x 0.5 m at 2 cm).
    assert!(
        stats.coarse_updates + stats.fine_updates < 6000,
        "{stats:?}"
    );
}

/// Merges the floor seen from 0.4 m into a tree of `resolution` on a pool of
/// `threads`, and compares the cells `cells` (in cells of that edge) with
/// the model; returns the merge's counters and the cells informed.
fn merge_floor_as_the_model(
    resolution: f64,
    threads: usize,
    cells: (
        std::ops::Range<i32>,
        std::ops::Range<i32>,
        std::ops::Range<i32>,
    ),
) -> (MergeStats, usize) {
    let (h, v) = (angles(70.0, 1.0), angles(60.0, 1.0));
    let grid = floor_grid(Vector3::new(0.0013, 0.0021, 0.4), &h, &v, 0.01);
    let options = MergeOptions::default();
    let mut tree = Octree::new(resolution);
    let stats = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| merge(&mut tree, &grid, &options));
    let centres = cell_centres(resolution, cells);
    (
        stats,
        assert_merged_as_the_model(&tree, &grid, &options, centres),
    )
}

#[test]
fn merge_equals_the_cell_model_evaluated_at_every_finest_cell() {
    // The coarse shortcuts (skip, whole-cell free) must not change any cell.
    let (stats, informed) = merge_floor_as_the_model(0.02, 2, (-12..12, -9..9, -3..24));
    assert!(stats.coarse_updates > 0, "{stats:?}");
    assert!(informed > 1000, "{informed}");
}

#[test]
fn merge_equals_the_cell_model_across_many_lattice_blocks_on_one_thread() {
    // 5 mm cells: the floor's view spans several of the merge's lattice
    // blocks (32 cells a side) along x and z, and on one thread one corner
    // cache serves them all in turn, so a value kept from an earlier block
    // would show here.
    let (_, informed) = merge_floor_as_the_model(0.005, 1, (-70..70, -2..2, -8..72));
    assert!(informed > 20_000, "{informed}");
}

#[test]
fn a_face_seven_tenths_of_a_millimetre_into_a_cell_row_is_occupied_everywhere() {
    // The plane z = 0.0207 with 1 cm cells: the row [0.02, 0.03) holds the
    // top 0.7 mm of the solid. Zero pose error, σ = 1 mm along the beam;
    // seen from 0.5 m above with 0.5° beams. With exact ranges the chord
    // model alone calls every cell of the face occupied. With ranges drawn
    // with that noise, a cell whose few beams all read long has an honest
    // probability below ½ (about 0.4): the risk level ε = 0.05 is what keeps
    // it occupied (docs/math.md §5.4).
    let (h, v) = (angles(30.0, 0.5), angles(30.0, 0.5));
    let top = 0.0207;
    for noise in [None, Some(1), Some(2), Some(3)] {
        let grid = plane_grid(Vector3::new(0.0013, 0.0021, 0.5), &h, &v, 0.001, top, noise);
        let mut tree = Octree::new(0.01);
        let options = MergeOptions {
            model: CellModel::with_risk(noise.map(|_| 0.05)),
            ..MergeOptions::default()
        };
        merge(&mut tree, &grid, &options);
        let mut cells = 0;
        for i in -10..10 {
            for j in -10..10 {
                let (x, y) = (i as f64 * 0.01 + 0.005, j as f64 * 0.01 + 0.005);
                let at = |z: f64| tree.value_at(&Point3::new(x, y, z));
                let surface = at(0.025).expect("the surface row is observed");
                assert!(
                    surface > 0.0,
                    "{noise:?}: ({x}, {y}) surface cell {surface}"
                );
                assert!(at(0.035).unwrap() < 0.0, "{noise:?}: the row above is free");
                cells += 1;
            }
        }
        assert_eq!(cells, 400);
    }
}

#[test]
fn viewpoint_order_does_not_matter_and_empty_grids_change_nothing() {
    let (h, v) = (angles(30.0, 1.0), angles(20.0, 1.0));
    let a = floor_grid(Vector3::new(0.0013, 0.0021, 0.4), &h, &v, 0.01);
    let b = floor_grid(Vector3::new(0.0513, -0.0379, 0.35), &h, &v, 0.006);
    let options = MergeOptions {
        clamp: Clamp::NONE,
        ..MergeOptions::default()
    };
    let (mut ab, mut ba) = (Octree::new(0.02), Octree::new(0.02));
    merge(&mut ab, &a, &options);
    merge(&mut ab, &b, &options);
    merge(&mut ba, &b, &options);
    merge(&mut ba, &a, &options);
    for i in -15..15 {
        for j in -15..15 {
            for k in -3..25 {
                let p = Point3::new(
                    i as f64 * 0.02 + 0.01,
                    j as f64 * 0.02 + 0.01,
                    k as f64 * 0.02 + 0.01,
                );
                match (ab.value_at(&p), ba.value_at(&p)) {
                    (Some(x), Some(y)) => assert!((x - y).abs() < 1e-5, "{p:?}"),
                    (x, y) => assert_eq!(x, y, "{p:?}"),
                }
            }
        }
    }
    // Two identical grids fuse like one grid fused twice.
    let a2 = floor_grid(Vector3::new(0.0013, 0.0021, 0.4), &h, &v, 0.01);
    let (mut twice, mut pair) = (Octree::new(0.02), Octree::new(0.02));
    merge(&mut twice, &a, &options);
    merge(&mut twice, &a, &options);
    merge(&mut pair, &a, &options);
    merge(&mut pair, &a2, &options);
    assert_eq!(to_ot(&twice), to_ot(&pair));
    // An empty grid is neutral: the tree stays bit-identical.
    let before = to_ot(&ab);
    let empty = local_grid(
        &Vector3::new(0.0, 0.0, 0.4),
        &Matrix3::zeros(),
        &looking_down(),
        Raster {
            horizontal: &h,
            vertical: &v,
        },
        &[],
        2.0,
    );
    merge(&mut ab, &empty, &options);
    assert_eq!(to_ot(&ab), before);
}

#[test]
fn ball_bins_are_a_superset() {
    let (h, v) = (angles(40.0, 1.0), angles(30.0, 1.0));
    let grid = floor_grid(Vector3::new(0.0, 0.0, 0.5), &h, &v, 0.01);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..300 {
        let centre = Vector3::new(
            rng.random_range(-0.4..0.4),
            rng.random_range(-0.4..0.4),
            rng.random_range(-0.2..0.8),
        );
        let radius = rng.random_range(0.001..0.2);
        let found = grid.ball_bins(&centre, radius);
        for _ in 0..1000 {
            let u = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if u.norm() > 1.0 {
                continue;
            }
            let p = centre + u * radius;
            let (r, _, _) = spherical(&(grid.scene_from_grid.transpose() * (p - grid.origin)));
            match (found, grid.bin_of(&p)) {
                (None, bin) => assert!(bin.is_none(), "a point of the ball is in the grid"),
                (Some(b), Some((a, e))) => {
                    let within = |(lo, hi): (usize, usize), x: usize| lo <= x && x <= hi;
                    assert!(
                        within(b.azimuth, a) && within(b.elevation, e),
                        "bin ({a},{e}) not in {b:?}"
                    );
                    assert!(b.range.0 <= r + 1e-12 && r <= b.range.1 + 1e-12);
                }
                (Some(b), None) => {
                    assert!(b.outside, "a point of the ball is outside but not flagged");
                }
            }
        }
    }
}

#[test]
fn a_grazing_view_never_certifies_a_cell_row_holding_a_sliver_of_solid() {
    // The plane z = 0.0207 (solid below) seen at grazing incidence from
    // 0.6 m away and 0.1 m up, 0.5° beams: hits land centimetres apart, so
    // most cells of the row [0.02, 0.03) hold 0.7 mm of solid that no beam
    // hits, under beams that cross their free top. A cell is free only when
    // its whole volume is seen in front of the surface (§5.4): with the risk
    // level ε = 0.05 no cell of that row is called free, while the rows
    // above are.
    let origin = Vector3::new(-0.6, 0.0, 0.12);
    let boresight = (Vector3::new(0.0, 0.0, 0.0207) - origin).normalize();
    let right = boresight.cross(&Vector3::z()).normalize();
    let down = boresight.cross(&right);
    let scene_from_camera = Matrix3::from_columns(&[right, down, boresight]);
    let (h, v) = (angles(30.0, 0.5), angles(10.0, 0.5));
    let top = 0.0207;
    let mut beams = Vec::new();
    for &vv in &v {
        for &hh in &h {
            let d = scene_from_camera
                * Vector3::new(vv.cos() * hh.sin(), vv.sin(), vv.cos() * hh.cos());
            beams.push(if d.z < 0.0 {
                BeamEnd::Hit {
                    point: origin + d * ((top - origin.z) / d.z),
                    covariance: Matrix3::identity() * 1e-6,
                }
            } else {
                BeamEnd::Miss { direction: d }
            });
        }
    }
    let raster = Raster {
        horizontal: &h,
        vertical: &v,
    };
    let grid = local_grid(
        &origin,
        &Matrix3::zeros(),
        &scene_from_camera,
        raster,
        &beams,
        2.0,
    );
    let mut tree = Octree::new(0.01);
    let options = MergeOptions {
        model: CellModel::with_risk(Some(0.05)),
        ..MergeOptions::default()
    };
    merge(&mut tree, &grid, &options);
    let (mut sliver_seen, mut above_seen, mut above_free) = (0, 0, 0);
    for i in -20..20 {
        for j in -5..5 {
            let (x, y) = (i as f64 * 0.01 + 0.005, j as f64 * 0.01 + 0.005);
            if let Some(l) = tree.value_at(&Point3::new(x, y, 0.025)) {
                sliver_seen += 1;
                let c = Vector3::new(x, y, 0.025);
                let direct = grid.ball_bins(&c, 0.005 * 3f64.sqrt()).and_then(|b| {
                    cell_occupancy(&grid, &options.model, &Cell::around(c, 0.005), &b)
                });
                assert!(
                    l >= 0.0,
                    "({x}, {y}): a cell holding solid called free ({l}), direct {direct:?}"
                );
            }
            if let Some(l) = tree.value_at(&Point3::new(x, y, 0.045)) {
                above_seen += 1;
                above_free += usize::from(l < 0.0);
            }
        }
    }
    assert!(sliver_seen > 100, "{sliver_seen}");
    assert!(
        above_free * 10 >= above_seen * 9 && above_seen > 100,
        "{above_free}/{above_seen}"
    );
}

/// `cell_occupancy` as it was before beams whose surface band misses a
/// cell were skipped: every beam's chord, the fallback whenever no centre
/// line crosses the cell (the corner test, untouched, is shared).
fn cell_occupancy_unskipped(
    grid: &LocalGrid,
    model: &CellModel,
    cell: &Cell,
    bins: &crate::mapping::spherical::BinBox,
) -> Option<f64> {
    use crate::mapping::chord::{origin_step, ray_box};
    use crate::mapping::merge::{combine, corner_free};
    let (centre, half) = (&cell.centre, cell.half);
    let max_range = grid.max_range;
    let inside = |beam, a: f64, b: f64| {
        model.split(beam, a, b, max_range).1 * origin_step(0.5 * (a + b), beam.sigma_origin)
    };
    let (mut hit, mut crossed) = (0.0f64, false);
    for a in bins.azimuth.0..=bins.azimuth.1 {
        for e in bins.elevation.0..=bins.elevation.1 {
            let (beams, inverse) = grid.bin_beams(a, e);
            for (beam, inv) in beams.iter().zip(inverse) {
                if let Some((t0, t1)) = ray_box(&grid.origin, inv, centre, half) {
                    crossed = true;
                    hit = hit.max(inside(beam, t0, t1));
                }
            }
        }
    }
    if !crossed {
        if let Some((a, e)) = grid.bin_of(centre) {
            for beam in grid.bin_beams(a, e).0 {
                hit = hit.max(inside(beam, bins.range.0, bins.range.1));
            }
        }
    }
    combine(model, hit, |i| corner_free(grid, model, &cell.corners[i]))
}

#[test]
fn skipping_beams_whose_band_misses_the_cell_changes_no_cell() {
    // A noisy floor seen from 0.5 m, cells of 1 and 5 cm around it (coarse
    // cells span many bins, most of whose bands miss them), with and without
    // a risk level: the same value, bit for bit.
    let (h, v) = (angles(40.0, 0.5), angles(30.0, 0.5));
    let grid = plane_grid(
        Vector3::new(0.0013, 0.0021, 0.5),
        &h,
        &v,
        0.003,
        FLOOR,
        Some(7),
    );
    let mut compared = 0;
    for model in [CellModel::default(), CellModel::with_risk(Some(0.05))] {
        for size in [0.01, 0.05] {
            let half = size / 2.0;
            let n = (0.4 / size) as i32;
            for i in -n..n {
                for j in -n..n {
                    for k in -3..(0.6 / size) as i32 {
                        let c = Vector3::new(
                            (i as f64 + 0.5) * size,
                            (j as f64 + 0.5) * size,
                            (k as f64 + 0.5) * size,
                        );
                        let Some(bins) = grid.ball_bins(&c, half * 3f64.sqrt()) else {
                            continue;
                        };
                        let cell = Cell::around(c, half);
                        let fast = cell_occupancy(&grid, &model, &cell, &bins);
                        let slow = cell_occupancy_unskipped(&grid, &model, &cell, &bins);
                        assert_eq!(
                            fast.map(f64::to_bits),
                            slow.map(f64::to_bits),
                            "{c:?} at {size} m"
                        );
                        compared += usize::from(slow.is_some_and(|p| p > 0.5));
                    }
                }
            }
        }
    }
    assert!(compared > 500, "{compared} cells with a surface compared");
}

#[test]
fn the_scanners_clearing_estimate_counts_the_cells_the_merge_evaluates() {
    // A viewpoint whose beams all miss: the merge updates the inside of its
    // field of view a node at a time and the cells on its boundary one by
    // one, as many as `Scanner::cleared_boundary_cells` estimates (measured:
    // 1.12 and 1.16 times; without the √3 layer, 1.94 and 2.01).
    use crate::sim::sensor::{ScannerSpec, SensorModel};
    for (fov, step, resolution) in [([40.0, 30.0], 1.0, 0.05), ([60.0, 10.0], 0.5, 0.02)] {
        let spec = ScannerSpec {
            model: SensorModel::Raster,
            horizontal_fov_deg: fov[0],
            horizontal_step_deg: Some(step),
            width: None,
            height: None,
            vertical_fov_deg: fov[1],
            vertical_step_deg: Some(step),
            min_range: 0.1,
            max_range: 2.0,
        };
        let scanner = spec.build().unwrap();
        let rotation = looking_down();
        let misses: Vec<BeamEnd> = scanner
            .directions()
            .iter()
            .map(|d| BeamEnd::Miss {
                direction: rotation * d,
            })
            .collect();
        let grid = local_grid(
            &Vector3::new(0.0013, 0.0021, 2.5),
            &(Matrix3::identity() * 1e-8),
            &rotation,
            Raster {
                horizontal: &scanner.horizontal_angles,
                vertical: &scanner.vertical_angles,
            },
            &misses,
            scanner.max_range,
        );
        let mut tree = Octree::new(resolution);
        let stats = merge(&mut tree, &grid, &MergeOptions::default());
        let ratio = stats.fine_updates as f64
            / crate::mapping::scan::cleared_boundary_cells(
                scanner.layout.half_angles.unwrap(),
                scanner.max_range,
                resolution,
            );
        assert!(
            (0.8..1.3).contains(&ratio),
            "{fov:?} at {resolution}: {stats:?}, ratio {ratio}"
        );
    }
}

#[test]
fn merge_equals_the_cell_model_with_surface_samples() {
    // Sparse beams (2.5°) over a noisy floor, 1 cm cells: many cells lie
    // between the beams' lines, where only surface samples cross them. The
    // beams' noise alternates between 1 and 6 mm (a checkerboard): a sample
    // blends its neighbours' bands, so its band may start before its own
    // bin's beams' (the merge must know).
    let (h, v) = (angles(40.0, 2.5), angles(30.0, 2.5));
    let origin = Vector3::new(0.0013, 0.0021, 0.4);
    let mixed = |i: usize, j: usize| {
        if (i + j).is_multiple_of(2) {
            0.001
        } else {
            0.006
        }
    };
    let plain = plane_grid_with(origin, &h, &v, FLOOR, Some(7), mixed);
    let mut grid = plain.clone();
    grid.add_surface_samples(
        &SampleGate::default(),
        (&RangeModel::NOISELESS, &Matrix3::identity()),
    );
    assert!(grid.samples().0.len() > 500, "{}", grid.samples().0.len());
    let options = MergeOptions::default();
    let (mut tree, mut without) = (Octree::new(0.01), Octree::new(0.01));
    let stats = merge(&mut tree, &grid, &options);
    merge(&mut without, &plain, &options);
    assert!(stats.coarse_updates > 0, "{stats:?}");
    let cells = || cell_centres(0.01, (-16..16, -12..12, -3..12));
    let informed = assert_merged_as_the_model(&tree, &grid, &options, cells());
    let changed = cells()
        .filter(|p| tree.value_at(p) != without.value_at(p))
        .count();
    assert!(informed > 5000 && changed > 50, "{informed} {changed}");
}
