use super::*;

const RES: f64 = 0.01;

/// A 20³ block of known cells around the origin: the layer `normal = 0`
/// occupied, the rest free; `hole` stays unknown.
fn plane(normal: usize, hole: Option<[i64; 3]>) -> Octree {
    let clamp = Clamp::OCTOMAP;
    let mut tree = Octree::new(RES);
    for x in -10..10i64 {
        for y in -10..10i64 {
            for z in -10..10i64 {
                let c = [x, y, z];
                if Some(c) == hole {
                    continue;
                }
                let p = Point3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) * RES;
                let key = tree.key(&p).unwrap();
                let v = if c[normal] == 0 { clamp.max } else { clamp.min };
                tree.update(&key, v, clamp);
            }
        }
    }
    tree
}

fn value(tree: &Octree, c: [i64; 3]) -> Option<f64> {
    let p = Point3::new(c[0] as f64 + 0.5, c[1] as f64 + 0.5, c[2] as f64 + 0.5) * RES;
    tree.value_at(&p).map(|l| probability(l as f64))
}

/// The expectation over a displacement N(0, σ²) across the plane, on the
/// cell lattice: Σ_i w_i P₀(k − i) / Σ_i w_i, w_i = exp(−i² res² / 2σ²).
fn across(k: i64, sigma: f64) -> f64 {
    let (hit, free) = (
        probability(Clamp::OCTOMAP.max as f64),
        probability(Clamp::OCTOMAP.min as f64),
    );
    let (mut sum, mut weight) = (0.0, 0.0);
    for i in -20..=20i64 {
        let w = (-0.5 * (i as f64 * RES / sigma).powi(2)).exp();
        sum += w * if k - i == 0 { hit } else { free };
        weight += w;
    }
    sum / weight
}

fn along(axis: usize, sigma: f64) -> Matrix3 {
    let mut c = Matrix3::zeros();
    c[(axis, axis)] = sigma * sigma;
    c
}

#[test]
fn a_displacement_across_a_surface_spreads_it_as_the_expectation_says() {
    let sigma = 0.012;
    for normal in 0..3 {
        let mut tree = plane(normal, None);
        let stats = expect_over_shared_motion(&mut tree, &|_| along(normal, sigma), Clamp::OCTOMAP)
            .unwrap();
        assert!(stats.changed > 0);
        for k in -4..=4i64 {
            let mut c = [2, -3, 1];
            c[normal] = k;
            let got = value(&tree, c).unwrap();
            let want = across(k, sigma).clamp(0.1192, 0.971);
            assert!(
                (got - want).abs() < 2e-3,
                "normal {normal}, {k} cells off the plane: {got} vs {want}"
            );
        }
    }
}

#[test]
fn an_isotropic_displacement_is_the_same_across_the_plane() {
    let sigma = 0.008;
    let mut tree = plane(2, None);
    let isotropic = Matrix3::identity() * sigma * sigma;
    expect_over_shared_motion(&mut tree, &|_| isotropic, Clamp::OCTOMAP).unwrap();
    for k in -3..=3i64 {
        let got = value(&tree, [0, 0, k]).unwrap();
        let want = across(k, sigma).clamp(0.1192, 0.971);
        assert!((got - want).abs() < 2e-3, "{k}: {got} vs {want}");
    }
}

#[test]
fn a_displacement_along_the_surface_changes_nothing() {
    for (normal, axis) in [(2, 0), (2, 1), (0, 2)] {
        let mut tree = plane(normal, None);
        let before = tree.leaves();
        let stats =
            expect_over_shared_motion(&mut tree, &|_| along(axis, 0.02), Clamp::OCTOMAP).unwrap();
        assert_eq!(stats.changed, 0, "normal {normal}, motion along {axis}");
        assert_eq!(tree.leaves(), before);
    }
}

#[test]
fn unknown_cells_stay_unknown_and_do_not_count() {
    let hole = [0, 0, 1];
    let mut tree = plane(2, Some(hole));
    let sigma = 0.012;
    expect_over_shared_motion(&mut tree, &|_| along(2, sigma), Clamp::OCTOMAP).unwrap();
    assert_eq!(value(&tree, hole), None);
    // Its neighbour across the plane averages over the known cells only.
    let got = value(&tree, [0, 0, -1]).unwrap();
    let (hit, free) = (
        probability(Clamp::OCTOMAP.max as f64),
        probability(Clamp::OCTOMAP.min as f64),
    );
    let (mut sum, mut weight) = (0.0, 0.0);
    for i in -20..=20i64 {
        if -1 - i == 1 {
            continue; // the hole
        }
        let w = (-0.5 * (i as f64 * RES / sigma).powi(2)).exp();
        sum += w * if -1 - i == 0 { hit } else { free };
        weight += w;
    }
    assert!(
        (got - sum / weight).abs() < 2e-3,
        "{got} vs {}",
        sum / weight
    );
}

#[test]
fn a_motion_under_half_a_cell_or_a_free_map_is_left_alone() {
    let mut tree = plane(2, None);
    let before = tree.leaves();
    let stats = expect_over_shared_motion(
        &mut tree,
        &|_| Matrix3::identity() * (0.1 * RES).powi(2),
        Clamp::OCTOMAP,
    )
    .unwrap();
    assert_eq!(stats, SharedMotionStats::default());
    assert_eq!(tree.leaves(), before);
    let mut free = Octree::new(RES);
    let key = free.key(&Point3::new(0.005, 0.005, 0.005)).unwrap();
    free.update(&key, Clamp::OCTOMAP.min, Clamp::OCTOMAP);
    let stats =
        expect_over_shared_motion(&mut free, &|_| Matrix3::identity() * 0.0004, Clamp::OCTOMAP)
            .unwrap();
    assert_eq!(stats.changed, 0);
}
