use super::*;
use crate::mapping::octree::CENTER;
use rand::{Rng, SeedableRng};
use std::collections::BTreeSet;

#[test]
fn axis_ray_visits_consecutive_cells() {
    let tree = Octree::new(0.1);
    let mut keys = Vec::new();
    assert!(ray_keys(
        &tree,
        &Point3::new(0.05, 0.05, 0.05),
        &Point3::new(0.95, 0.05, 0.05),
        &mut keys
    ));
    let xs: Vec<u16> = keys.iter().map(|k| k.0[0]).collect();
    assert_eq!(xs, (32768..32777).collect::<Vec<_>>());
    assert!(keys.iter().all(|k| k.0[1] == 32768 && k.0[2] == 32768));
}

#[test]
fn diagonal_ray_is_face_connected_and_reaches_the_end() {
    let tree = Octree::new(0.05);
    let origin = Point3::new(0.013, -0.02, 0.031);
    let end = Point3::new(1.37, 0.61, -0.43);
    let mut keys = Vec::new();
    assert!(ray_keys(&tree, &origin, &end, &mut keys));
    assert_eq!(keys[0], tree.key(&origin).unwrap());
    let last = tree.key(&end).unwrap();
    let mut all = keys.clone();
    all.push(last);
    for pair in all.windows(2) {
        let steps: i32 = (0..3)
            .map(|a| (pair[0].0[a] as i32 - pair[1].0[a] as i32).abs())
            .sum();
        assert_eq!(steps, 1, "{pair:?}");
    }
    // Every cell the segment crosses lies on it (sampled densely).
    for i in 0..=10_000 {
        let p = origin + (end - origin) * (i as f64 / 10_000.0);
        let k = tree.key(&p).unwrap();
        assert!(all.contains(&k), "{p:?}");
    }
}

#[test]
fn scan_marks_free_then_occupied_and_occupied_wins() {
    let mut tree = Octree::new(0.1);
    let origin = Point3::new(0.05, 0.05, 0.05);
    let hits = [Point3::new(0.55, 0.05, 0.05), Point3::new(0.35, 0.05, 0.05)];
    let mut updater = RayUpdater::default();
    updater.insert_scan(&mut tree, &origin, &hits, &[Vector3::y()], 1.0);
    let at = |x: f64, y: f64| tree.value_at(&Point3::new(x, y, 0.05));
    assert_eq!(at(0.05, 0.05), Some(LOG_ODDS_MISS));
    assert_eq!(at(0.25, 0.05), Some(LOG_ODDS_MISS));
    // Hit by one ray, traversed by the other: occupied, updated once.
    assert_eq!(at(0.35, 0.05), Some(LOG_ODDS_HIT));
    assert_eq!(at(0.55, 0.05), Some(LOG_ODDS_HIT));
    assert_eq!(at(0.65, 0.05), None);
    // The no-return beam carves up to max range only.
    assert_eq!(at(0.05, 0.95), Some(LOG_ODDS_MISS));
    assert_eq!(at(0.05, 1.15), None);
}

/// The scan's cells the slow way, OctoMap's `insertPointCloud` transcribed
/// ray by ray (`computeUpdate`): the `float` origin and points (hits, then
/// each no-return beam's point at twice `max_range`), a point beyond the
/// maximum range cut at it in `float`, every ray's [`octomap_ray_keys`];
/// the hit cells occupied and winning, each cell updated once.
fn reference_scan(
    tree: &mut Octree,
    origin: &Point3,
    hits: &[Point3],
    misses: &[Vector3],
    max_range: f64,
) {
    let mut free = BTreeSet::new();
    let mut occupied = BTreeSet::new();
    let o = origin.map(|c| c as f32);
    let max_range_f32 = max_range as f32;
    let far = misses.iter().map(|d| origin + d * (2.0 * max_range));
    for p in hits.iter().copied().chain(far) {
        let p = p.map(|c| c as f32);
        let d = p - o;
        let norm = f64::from(d.x * d.x + d.y * d.y + d.z * d.z).sqrt();
        let (end, hit) = if norm <= f64::from(max_range_f32) {
            (p, true)
        } else {
            let direction = d / norm as f32;
            (o + direction * max_range_f32, false)
        };
        let (origin, end) = (o.map(f64::from), end.map(f64::from));
        let keys = octomap_ray_keys(tree.resolution(), &origin, &end);
        free.extend(keys.iter().map(Key::morton));
        if let (true, Some(key)) = (hit, octomap_key(tree.resolution(), &end)) {
            occupied.insert(key.morton());
        }
    }
    for code in free.difference(&occupied) {
        tree.update(&Key::from_morton(*code), LOG_ODDS_MISS, Clamp::OCTOMAP);
    }
    for code in &occupied {
        tree.update(&Key::from_morton(*code), LOG_ODDS_HIT, Clamp::OCTOMAP);
    }
}

/// The ways a scan's rays are walked: bitmap four at a time (where the CPU
/// has AVX2), bitmap one at a time, hash set.
const WALKS: [(Option<usize>, bool); 3] = [(None, false), (None, true), (Some(0), false)];

/// Inserts the scan every way of [`WALKS`] and checks each tree against
/// the ray-by-ray [`reference_scan`]; returns the reference's leaf count.
fn assert_every_walk_matches_the_reference(
    res: f64,
    origin: &Point3,
    hits: &[Point3],
    misses: &[Vector3],
    max_range: f64,
) -> usize {
    let mut reference = Octree::new(res);
    reference_scan(&mut reference, origin, hits, misses, max_range);
    for ((dense_limit, one_at_a_time), alone) in
        WALKS.into_iter().flat_map(|w| [(w, false), (w, true)])
    {
        let mut tree = Octree::new(res);
        let mut updater = RayUpdater {
            dense_limit,
            one_at_a_time,
            alone,
            ..RayUpdater::default()
        };
        updater.insert_scan(&mut tree, origin, hits, misses, max_range);
        assert_eq!(updater.free.dense, dense_limit.is_none());
        assert_eq!(
            tree.leaves(),
            reference.leaves(),
            "{dense_limit:?} {one_at_a_time} alone {alone}"
        );
    }
    reference.leaves().len()
}

#[test]
fn bitmap_and_hash_set_scans_equal_the_ray_by_ray_reference() {
    // Rays in every direction and of every length from an off-grid
    // origin, with the awkward ones: parallel to axes and planes,
    // ending on cell borders and corners, inside the origin's cell,
    // beyond max range; and rays without return.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    let res = 0.05;
    let origin = Point3::new(0.013, -0.031, 0.257);
    let mut hits: Vec<Point3> = (0..3000)
        .map(|_| {
            let d =
                Vector3::new(rng.random(), rng.random(), rng.random()) * 2.0 - Vector3::repeat(1.0);
            origin + d * rng.random_range(0.0..1.6)
        })
        .collect();
    for axis in 0..3 {
        for sign in [-1.0, 1.0] {
            let mut d = Vector3::zeros();
            d[axis] = sign * 0.83;
            hits.push(origin + d);
            d[(axis + 1) % 3] = 0.41;
            hits.push(origin + d);
        }
    }
    hits.extend((-8..8).map(|i| Point3::new(i as f64 * res, 0.3, -0.2)));
    hits.extend((-8..8).map(|i| Point3::new(i as f64 * res, i as f64 * res, 0.5)));
    // On borders behind the origin: walks that end one cell past the
    // end point's cell (rounding), outside the box of the ends' keys.
    hits.extend((-8..8).flat_map(|i| {
        let i = i as f64 * res;
        [
            Point3::new(i, -0.65, -i - 0.3),
            Point3::new(-0.55, i, 0.75 * i),
            Point3::new(0.7 * i, 0.4 * i, -0.45),
        ]
    }));
    hits.push(origin + Vector3::new(0.004, -0.002, 0.001));
    let misses: Vec<Vector3> = (0..200)
        .map(|_| {
            Vector3::new(rng.random(), rng.random(), rng.random()).normalize()
                - Vector3::repeat(0.5)
        })
        .map(|d| d.normalize())
        .collect();
    let max_range = 1.2;
    let leaves = assert_every_walk_matches_the_reference(res, &origin, &hits, &misses, max_range);
    assert!(leaves > 1000, "{leaves} leaves");
}

#[test]
fn a_walk_that_ends_past_its_end_cell_marks_that_cell() {
    // Ends on a cell border (`float` points, found by search): rounding
    // takes the walk one cell past the end point's cell, outside the box of
    // the two keys (which the bitmap's margin covers), as OctoMap's walk
    // does.
    let rays = [
        (
            [0.1272536814212799, -0.18958012759685516, 0.4837588965892792],
            [-1.850000023841858, -1.399999976158142, 0.8824385404586792],
        ),
        (
            [
                0.14671148359775543,
                0.14392191171646118,
                0.13756421208381653,
            ],
            [
                -1.3000000715255737,
                -1.2121376991271973,
                0.05000000074505806,
            ],
        ),
    ];
    for (origin, end) in rays.map(|(o, e)| (Point3::from(o), Point3::from(e))) {
        let keys = octomap_ray_keys(0.05, &origin, &end);
        let stop = octomap_key(0.05, &end).unwrap();
        let d = end - origin;
        let past = |k: &Key| {
            (0..3).any(|a| (k.0[a] as i64 - stop.0[a] as i64) as f64 * d[a].signum() > 0.0)
        };
        assert!(keys.iter().any(past), "the case is exercised");
        assert_every_walk_matches_the_reference(0.05, &origin, &[end], &[], 5.0);
    }
}

#[test]
fn a_custom_rule_sets_the_steps_and_the_clamp() {
    let rule = UpdateRule {
        hit: 0.25,
        miss: -0.125,
        clamp: Clamp {
            min: -0.2,
            max: 0.375,
        },
    };
    let mut tree = Octree::new(0.1);
    let origin = Point3::new(0.05, 0.05, 0.05);
    let hits = [Point3::new(0.55, 0.05, 0.05)];
    let mut updater = RayUpdater::new(rule);
    let at = |tree: &Octree, x: f64| tree.value_at(&Point3::new(x, 0.05, 0.05));
    updater.insert_scan(&mut tree, &origin, &hits, &[], 1.0);
    assert_eq!(at(&tree, 0.25), Some(-0.125));
    assert_eq!(at(&tree, 0.55), Some(0.25));
    updater.insert_scan(&mut tree, &origin, &hits, &[], 1.0);
    assert_eq!(at(&tree, 0.25), Some(-0.2), "clamped below");
    assert_eq!(at(&tree, 0.55), Some(0.375), "clamped above");
}

/// Random measured points around `origin` with the awkward ones: on cell
/// borders, level with the origin on one or two axes (no steps there),
/// in the origin's cell, outside the tree, NaN; a third beyond 2 m.
fn awkward_hits(origin: &Point3, res: f64, n: usize, seed: u64) -> Vec<Point3> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut hits: Vec<Point3> = (0..n)
        .map(|i| {
            // The first half within 2 m (a cube of ±1.1 m), the rest within
            // ±2.5 m, most beyond 2 m.
            let half = if i < n / 2 { 1.1 } else { 2.5 };
            let p =
                Vector3::new(rng.random(), rng.random(), rng.random()) * 2.0 - Vector3::repeat(1.0);
            let mut p = origin + p * half;
            match i % 7 {
                0 => p.x = (p.x / res).round() * res,
                1 => p.y = origin.y,
                2 => (p.x, p.z) = (origin.x, origin.z),
                3 => p = origin + (p - origin) * 1e-3,
                _ => {}
            }
            p
        })
        .collect();
    hits.push(Point3::new(1e7, 0.0, 0.0));
    hits.push(Point3::new(0.1, f64::NAN, 0.0));
    hits
}

/// Directions of beams without return, with axis-parallel ones.
fn awkward_misses(n: usize, seed: u64) -> Vec<Vector3> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut misses: Vec<Vector3> = (0..n)
        .map(|_| {
            (Vector3::new(rng.random(), rng.random(), rng.random()) - Vector3::repeat(0.5))
                .normalize()
        })
        .collect();
    misses.extend([
        Vector3::x(),
        -Vector3::y(),
        Vector3::z(),
        Vector3::new(0.6, 0.0, -0.8),
    ]);
    misses
}

#[test]
fn four_lanes_set_up_and_walk_rays_bit_for_bit_as_one_at_a_time() {
    #[cfg(target_arch = "x86_64")]
    if !std::arch::is_x86_feature_detected!("avx2") {
        eprintln!("no AVX2 on this CPU: both ways walk one ray at a time");
    }
    let res = 0.05;
    let origin = Point3::new(0.013, -0.031, 0.257);
    // 4001 hits and 1003 misses: the last chunks of four are partial.
    let hits = awkward_hits(&origin, res, 3999, 5);
    let misses = awkward_misses(999, 6);
    // Some hits beyond the walks' 2 m: truncated, they only carve.
    let beyond = hits.iter().filter(|p| (*p - origin).norm() > 2.0).count();
    assert!(
        beyond > 200 && hits.len() - beyond > 1000,
        "{beyond} beyond"
    );
    let walks = assert_lanes_walk_as_one(res, &origin, &hits, &misses);
    assert!(walks > 4000, "{walks} walks");
}

#[test]
fn lanes_break_ties_between_axes_as_one_at_a_time() {
    // From a cell's centre along diagonals, every crossing is a tie
    // between two or three axes (exactly: the spacings are equal), which
    // OctoMap's choice breaks toward z, then y.
    let res = 0.05;
    let origin = Octree::new(res).center(&Key([32768 + 3, 32768 - 2, 32768 + 5]), 16);
    let mut misses = Vec::new();
    for sx in [-1.0, 0.0, 1.0] {
        for sy in [-1.0, 0.0, 1.0] {
            for sz in [-1.0, 0.0, 1.0] {
                let d = Vector3::new(sx, sy, sz);
                if d.norm() > 0.0 {
                    misses.push(d.normalize());
                }
            }
        }
    }
    let hits: Vec<Point3> = misses
        .iter()
        .flat_map(|d| (1..=7).map(move |k| origin + d * (0.37 * f64::from(k))))
        .collect();
    let walks = assert_lanes_walk_as_one(res, &origin, &hits, &misses);
    assert!(walks > 180, "{walks} walks");
}

/// Walks the rays of `hits` and `misses` from `origin` one at a time, four
/// at a time and eight at a time (where the CPU has the vectors) and
/// asserts the same set-up and the same cells; the number of walks.
fn assert_lanes_walk_as_one(
    res: f64,
    origin: &Point3,
    hits: &[Point3],
    misses: &[Vector3],
) -> usize {
    let max_range = 2.0;
    let origin = *origin;
    let tree = Octree::new(res);
    let start = octomap_key(res, &origin).unwrap();
    let (lo, hi) = key_box(&tree, start, &origin, (hits, misses), max_range);
    let walked = |lanes: bool, wide: bool, alone: bool| {
        let (mut free, mut occupied) = (CellSet::default(), CellSet::default());
        let lo = lo.map(|v| v - 2);
        let hi = hi.map(|v| v + 2);
        free.reset(lo, hi, DENSE_LIMIT);
        occupied.reset(lo, hi, DENSE_LIMIT);
        let dense = DenseWalk {
            tree: &tree,
            origin,
            float_origin: float::point(&origin),
            max_range,
            start: free.index(&start),
            start_key: start,
            free: &free,
            occupied: &occupied,
            strides: std::array::from_fn(|axis| free.stride(axis)),
            lanes,
            wide,
        };
        let mut walks = Vec::new();
        dense.begin_hits(hits, &mut walks);
        dense.begin_misses(misses, &mut walks);
        // Bit for bit, -0.0 and 0.0 apart.
        let set_up = format!("{walks:?}");
        if alone {
            let first = dense.start;
            dense::mark_exclusive(&mut free.bits, first, &walks, lanes, wide);
        } else {
            dense.mark_rays(&walks);
        }
        let bits =
            |set: &CellSet| -> Vec<u64> { set.bits.iter().map(|w| w.load(Relaxed)).collect() };
        (walks.len(), set_up, bits(&free), bits(&occupied))
    };
    let (four, one) = (walked(true, false, false), walked(false, false, false));
    assert_eq!(four.1, one.1, "the walks' set-up");
    assert!(four.2 == one.2, "the free cells");
    assert!(four.3 == one.3, "the occupied cells");
    // Four lanes given the bitmap to own: no owned four-lane walk, so
    // `mark_exclusive` falls back to the shared one, and the same cells.
    let four_alone = walked(true, false, true);
    assert!(four_alone.2 == one.2, "the free cells, four lanes alone");
    assert!(
        four_alone.3 == one.3,
        "the occupied cells, four lanes alone"
    );
    // Eight lanes (AVX-512) mark the same cells, sharing the bitmap or
    // owning it (each step's words gathered at once).
    #[cfg(target_arch = "x86_64")]
    if !std::arch::is_x86_feature_detected!("avx512f") {
        eprintln!("no AVX-512F on this CPU: eight lanes not compared");
    }
    for alone in [false, true] {
        let eight = walked(true, true, alone);
        assert!(
            eight.2 == one.2,
            "the free cells, eight lanes, alone {alone}"
        );
        assert!(
            eight.3 == one.3,
            "the occupied cells, eight lanes, alone {alone}"
        );
    }
    one.0
}

#[test]
fn a_scan_with_ends_outside_the_tree_walks_the_others() {
    // The origin near the tree's edge (±1638.4 m at 5 cm): many ends have
    // no key, so the box of keys is found key by key.
    let res = 0.05;
    let origin = Point3::new(1637.9, 0.01, -0.02);
    let hits: Vec<Point3> = awkward_hits(&origin, res, 400, 9)
        .into_iter()
        .filter(|p| !p.x.is_nan() && p.x < 1e6)
        .collect();
    assert!(hits.iter().any(|p| Octree::new(res).key(p).is_none()));
    let misses = awkward_misses(20, 10);
    let leaves = assert_every_walk_matches_the_reference(res, &origin, &hits, &misses, 2.0);
    assert!(leaves > 100, "{leaves} leaves");
}

/// OctoMap's `coordToKeyChecked` of the `float` point `p`, transcribed:
/// `floor(x · (1/res)) + 2¹⁵` if in `[0, 2¹⁶)` on every axis.
fn octomap_key(res: f64, p: &Point3) -> Option<Key> {
    let factor = 1.0 / res;
    let mut key = [0u16; 3];
    for (k, c) in key.iter_mut().zip(p.iter()) {
        let scaled = (f64::from(*c as f32) * factor).floor() + CENTER as f64;
        if !(0.0..65536.0).contains(&scaled) {
            return None;
        }
        *k = scaled as u16;
    }
    Some(Key(key))
}

/// OctoMap's `computeRayKeys` of one `float` ray, transcribed: its keys
/// (`floor(x · (1/res))`), its `float` direction and length, its `double`
/// crossings; every cell before the end's.
fn octomap_ray_keys(res: f64, origin: &Point3, end: &Point3) -> Vec<Key> {
    let (o, e) = (origin.map(|c| c as f32), end.map(|c| c as f32));
    let (Some(start), Some(stop)) = (octomap_key(res, origin), octomap_key(res, end)) else {
        return Vec::new();
    };
    if start == stop {
        return Vec::new();
    }
    let d = e - o;
    let length = f64::from(d.x * d.x + d.y * d.y + d.z * d.z).sqrt() as f32;
    let direction = d / length;
    let mut step = [0i32; 3];
    let (mut t_max, mut t_delta) = ([f64::MAX; 3], [f64::MAX; 3]);
    for i in 0..3 {
        step[i] = if direction[i] > 0.0 {
            1
        } else if direction[i] < 0.0 {
            -1
        } else {
            0
        };
        if step[i] != 0 {
            let mut border = ((start.0[i] as i64 - CENTER) as f64 + 0.5) * res;
            border += f64::from((f64::from(step[i]) * res * 0.5) as f32);
            t_max[i] = (border - f64::from(o[i])) / f64::from(direction[i]);
            t_delta[i] = res / f64::from(direction[i]).abs();
        }
    }
    let (mut keys, mut current) = (vec![start], start);
    loop {
        let dim = if t_max[0] < t_max[1] {
            if t_max[0] < t_max[2] {
                0
            } else {
                2
            }
        } else if t_max[1] < t_max[2] {
            1
        } else {
            2
        };
        current.0[dim] = (current.0[dim] as i32 + step[dim]) as u16;
        t_max[dim] += t_delta[dim];
        if current == stop || t_max.iter().copied().fold(f64::MAX, f64::min) > f64::from(length) {
            return keys;
        }
        keys.push(current);
    }
}

#[test]
fn a_discretized_scan_is_octomaps_discrete_update_every_way_it_is_walked() {
    // Hits and no-return beams, reduced as OctoMap's `insertPointCloud(...,
    // discretize = true)` reduces them, against OctoMap's update
    // transcribed: each cell's class and count. (Rays to cell centres tie
    // between axes often enough that walking them in `f64` instead of
    // OctoMap's `float` fails here.)
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let (res, max_range) = (0.05, 1.2);
    let origin = Point3::new(0.013, -0.031, 0.257);
    let direction = |rng: &mut rand_chacha::ChaCha8Rng| {
        (Vector3::new(rng.random(), rng.random(), rng.random()) * 2.0 - Vector3::repeat(1.0))
            .normalize()
    };
    let hits: Vec<Point3> = (0..4000)
        .map(|_| origin + direction(&mut rng) * rng.random_range(0.0..1.5))
        .collect();
    let misses: Vec<Vector3> = (0..300).map(|_| direction(&mut rng)).collect();
    let mut scan = DiscreteScan::default();
    let tree = Octree::new(res);
    let centres = scan
        .fill(&tree, &origin, (&hits, &misses), max_range)
        .to_vec();
    assert!(centres.len() < hits.len() + misses.len());
    let leaves = assert_every_walk_matches_the_reference(res, &origin, &centres, &[], max_range);
    assert!(leaves > 1000, "{leaves} leaves");
}
