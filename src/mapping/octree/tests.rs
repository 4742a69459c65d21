use super::*;
use rand::{Rng, SeedableRng};
use std::collections::HashMap;

#[test]
fn keys_and_centres_follow_octomap() {
    let tree = Octree::new(0.05);
    let k = tree.key(&Point3::new(0.01, -0.01, 0.12)).unwrap();
    assert_eq!(k, Key([32768, 32767, 32770]));
    let c = tree.center(&k, DEPTH);
    assert!((c - Point3::new(0.025, -0.025, 0.125)).norm() < 1e-12);
    // The depth-15 node holding it spans 0.1 m, from key 32768 (x) and 32766 (y).
    let c15 = tree.center(&k, 15);
    assert!((c15 - Point3::new(0.05, -0.05, 0.15)).norm() < 1e-12);
    assert_eq!(k.child_at(15), 2);
    assert!(tree.key(&Point3::new(1e9, 0.0, 0.0)).is_none());
    assert_eq!(Key::unpack(k.packed()), k);
}

#[test]
fn keys_floor_like_octomap_on_every_side_of_a_cell_border() {
    // OctoMap: floor(coordinate · (1/resolution)) + 2^15. Checked against
    // `f64::floor` on borders, just beside them, and at random.
    let tree = Octree::new(0.05);
    // OctoMap's coordToKey: floor(resolution_factor * coordinate), the
    // factor 1/res (a division rounds 0.3 / 0.05 down to 5.999...).
    let reference = |v: f64| {
        let k = (v * (1.0 / 0.05)).floor();
        if !k.is_finite() {
            return None;
        }
        let k = k as i64 + CENTER;
        (0..1 << 16).contains(&k).then_some(k as u16)
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let mut values = vec![
        0.0,
        -0.0,
        1638.4,
        -1638.4,
        -1638.45,
        1638.35,
        f64::NAN,
        f64::INFINITY,
    ];
    for i in -200..200 {
        let border = i as f64 * 0.05;
        values.extend([border, border.next_up(), border.next_down()]);
    }
    values.extend((0..10_000).map(|_| rng.random_range(-2000.0..2000.0)));
    for v in values {
        let key = tree.key(&Point3::new(v, 0.0, 0.0)).map(|k| k.0[0]);
        assert_eq!(key, reference(v), "x = {v}");
    }
    let key = tree.key(&Point3::new(0.3, 0.0, 0.0)).unwrap();
    assert_eq!(key.0[0] as i64 - CENTER, 6, "0.3 · 20 = 6, not 0.3 / 0.05");
}

/// The reference: a map of finest cells, no pruning, no inner nodes.
fn reference_query(map: &HashMap<Key, f32>, key: &Key, depth: u8) -> Option<f32> {
    let shift = DEPTH - depth;
    map.iter()
        .filter(|(k, _)| (0..3).all(|a| (k.0[a] as u32) >> shift == (key.0[a] as u32) >> shift))
        .map(|(_, v)| *v)
        .fold(None, |acc: Option<f32>, v| {
            Some(acc.map_or(v, |a| a.max(v)))
        })
}

#[test]
fn pruned_tree_answers_every_query_like_the_unpruned_reference() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut tree = Octree::new(0.1);
    let mut map: HashMap<Key, f32> = HashMap::new();
    // Clustered updates so that whole blocks fill and prune.
    for _ in 0..6000 {
        let key = Key([
            32768 + rng.random_range(0..8),
            32768 + rng.random_range(0..8),
            32760 + rng.random_range(0..4),
        ]);
        let delta = if rng.random_bool(0.9) { 0.85 } else { -0.4 };
        tree.update(&key, delta, Clamp::OCTOMAP);
        let v = map.entry(key).or_insert(0.0);
        *v = (*v + delta).clamp(Clamp::OCTOMAP.min, Clamp::OCTOMAP.max);
    }
    let stats = tree.stats();
    assert!(
        stats.leaves < map.len(),
        "saturated blocks must prune: {stats:?}"
    );
    for x in 32766..32778u16 {
        for y in 32766..32778u16 {
            for z in 32758..32766u16 {
                let key = Key([x, y, z]);
                for depth in [16u8, 15, 14, 13, 0] {
                    assert_eq!(
                        tree.query(&key, depth),
                        reference_query(&map, &key, depth),
                        "{key:?} at depth {depth}"
                    );
                }
            }
        }
    }
    // Every reported leaf covers cells of one value.
    let mut covered = 0usize;
    tree.visit_leaves(|leaf| covered += 1usize << (3 * (DEPTH - leaf.depth) as usize));
    assert_eq!(covered, map.len());
}

#[test]
fn region_update_equals_cell_updates() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    let mut coarse = Octree::new(0.05);
    let mut fine = Octree::new(0.05);
    for _ in 0..200 {
        let key = Key([
            32768 + rng.random_range(0..16),
            32768 + rng.random_range(0..16),
            32768 + rng.random_range(0..16),
        ]);
        let delta = rng.random_range(-1.0..1.0f32);
        coarse.update(&key, delta, Clamp::NONE);
        fine.update(&key, delta, Clamp::NONE);
    }
    // +0.5 over the depth-13 node holding key 32768.. (8 cells a side).
    let corner = Key([32768, 32768, 32768]);
    coarse.update_region(&corner, 13, 0.5, Clamp::NONE);
    for x in 0..8u16 {
        for y in 0..8u16 {
            for z in 0..8u16 {
                fine.update(&Key([32768 + x, 32768 + y, 32768 + z]), 0.5, Clamp::NONE);
            }
        }
    }
    assert_eq!(coarse, fine);
    // An untouched region updated as a whole stays one coarse leaf.
    let mut tree = Octree::new(0.05);
    tree.update_region(&Key([0, 0, 0]), 10, -0.4, Clamp::OCTOMAP);
    let stats = tree.stats();
    assert_eq!(stats.leaves, 1);
    assert_eq!(tree.leaves()[0].depth, 10);
    assert_eq!(tree.query(&Key([5, 7, 63]), 16), Some(-0.4));
}

#[test]
fn octomap_constants_are_its_logodds() {
    assert_eq!(LOG_ODDS_HIT, logodds(0.7));
    assert_eq!(LOG_ODDS_MISS, logodds(0.4));
    assert_eq!(Clamp::OCTOMAP.min, logodds(0.1192));
    assert_eq!(Clamp::OCTOMAP.max, logodds(0.971));
}

#[test]
fn clamping_saturates_at_octomap_bounds() {
    let mut tree = Octree::new(0.02);
    let key = Key([40000, 40000, 40000]);
    for _ in 0..10 {
        tree.update(&key, 0.847, Clamp::OCTOMAP);
    }
    assert_eq!(tree.query(&key, DEPTH), Some(Clamp::OCTOMAP.max));
    for _ in 0..20 {
        tree.update(&key, -0.405, Clamp::OCTOMAP);
    }
    assert_eq!(tree.query(&key, DEPTH), Some(Clamp::OCTOMAP.min));
    assert_eq!(tree.query(&Key([1, 1, 1]), DEPTH), None);
    let stats = tree.stats();
    assert_eq!((stats.leaves, stats.inner, stats.nodes), (1, 16, 17));
}

#[test]
fn morton_codes_round_trip_and_order_depth_first() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    for _ in 0..1000 {
        let key = Key([rng.random(), rng.random(), rng.random()]);
        assert_eq!(Key::from_morton(key.morton()), key);
        for depth in 0..16u8 {
            assert_eq!(
                ((key.morton() >> (3 * (15 - depth))) & 7) as usize,
                key.child_at(depth)
            );
        }
    }
}

#[test]
fn sorted_batch_update_equals_one_by_one() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
    for round in 0..20 {
        let (mut batch, mut single) = (Octree::new(0.05), Octree::new(0.05));
        for _ in 0..5 {
            let mut codes: Vec<u64> = (0..rng.random_range(1..800))
                .map(|_| {
                    Key([
                        32760 + rng.random_range(0..16),
                        32760 + rng.random_range(0..16),
                        32766 + rng.random_range(0..8),
                    ])
                    .morton()
                })
                .collect();
            codes.sort_unstable();
            codes.dedup();
            let delta = if rng.random_bool(0.6) {
                LOG_ODDS_HIT
            } else {
                LOG_ODDS_MISS
            };
            let clamp = if round % 2 == 0 {
                Clamp::OCTOMAP
            } else {
                Clamp::NONE
            };
            batch.update_sorted(&codes, delta, clamp);
            for c in &codes {
                single.update(&Key::from_morton(*c), delta, clamp);
            }
            assert_eq!(batch, single);
            assert_eq!(batch.stats().nodes, single.stats().nodes);
        }
    }
}

#[test]
fn depth_first_changes_equal_one_by_one() {
    // Cells and regions (nodes of depth 12 to 15) mixed, in depth-first
    // order, over a few rounds on the same trees: changes meet pruned leaves,
    // unknown cells, clamped values and regions over finer structure.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
    for round in 0..30 {
        let (mut batch, mut single) = (Octree::new(0.05), Octree::new(0.05));
        let clamp = if round % 2 == 0 {
            Clamp::OCTOMAP
        } else {
            Clamp::NONE
        };
        for _ in 0..6 {
            let mut nodes: Vec<(u64, u8)> = (0..rng.random_range(1..400))
                .map(|_| {
                    let depth = if rng.random_bool(0.7) {
                        DEPTH
                    } else {
                        rng.random_range(12..DEPTH)
                    };
                    let mask = !0u16 << (DEPTH - depth);
                    let key = Key([
                        (32752 + rng.random_range(0..32)) & mask,
                        (32752 + rng.random_range(0..32)) & mask,
                        (32760 + rng.random_range(0..16)) & mask,
                    ]);
                    (key.morton(), depth)
                })
                .collect();
            nodes.sort_unstable();
            // Keep a node only when it starts past the last kept one's cells.
            let mut end = 0u64;
            nodes.retain(|&(code, depth)| {
                let keep = code >= end;
                if keep {
                    end = code + (1u64 << (3 * (DEPTH - depth) as u32));
                }
                keep
            });
            let changes: Vec<(u64, u8, f32)> = nodes
                .iter()
                .map(|&(code, depth)| {
                    let delta = match rng.random_range(0..3) {
                        0 => LOG_ODDS_HIT,
                        1 => LOG_ODDS_MISS,
                        _ => 3.0 * rng.random_range(-1.0..1.0f32),
                    };
                    (code, depth, delta)
                })
                .collect();
            batch.update_depth_first(changes.iter().copied(), clamp);
            for &(code, depth, delta) in &changes {
                let key = Key::from_morton(code);
                if depth == DEPTH {
                    single.update(&key, delta, clamp);
                } else {
                    single.update_region(&key, depth, delta, clamp);
                }
            }
            assert_eq!(batch, single);
            assert_eq!(batch.stats().nodes, single.stats().nodes);
        }
    }
}

#[test]
fn a_parent_of_finest_cells_costs_four_bytes_and_stores_no_value() {
    assert_eq!(std::mem::size_of::<ParentSlot>(), 4);
    assert_eq!(std::mem::size_of::<Node>(), 8);
    // One depth-14 node's 64 cells, each its own value: 8 parents with cells.
    let mut tree = Octree::new(0.05);
    for code in 0..64u64 {
        tree.update(&Key::from_morton(code), 0.01 * code as f32, Clamp::NONE);
    }
    tree.shrink_to_fit();
    // The root and one block of eight per depth 1–14; one block of parents;
    // eight blocks of cells; no leaf value.
    assert_eq!(tree.nodes.items.len(), 1 + 14 * 8);
    assert_eq!(tree.parents.items.len(), 8);
    assert_eq!(tree.finest.items.len(), 64);
    assert!(tree.leaf_values.items.is_empty());
    assert_eq!(tree.pool_bytes(), (1 + 14 * 8) * 8 + 8 * 4 + 64 * 4);
    // Each parent answers the max of its cells.
    for parent in 0..8u64 {
        let key = Key::from_morton(8 * parent);
        assert_eq!(tree.query(&key, 15), Some(0.01 * (8 * parent + 7) as f32));
    }
    assert_eq!(tree.query(&Key::from_morton(0), 14), Some(0.01 * 63.0));
}

#[test]
fn pruning_and_expanding_a_parent_again_and_again_reuses_its_slots() {
    // Eight equal cells prune into a depth-15 leaf (a leaf value); a miss on
    // one cell expands it again (the value is freed). Nothing may pile up.
    let mut tree = Octree::new(0.05);
    let cells: Vec<u64> = (0..8).collect();
    for _ in 0..100 {
        tree.update_sorted(&cells, 5.0, Clamp::OCTOMAP);
        assert_eq!(tree.leaves().len(), 1, "eight clamped cells prune");
        tree.update(&Key::from_morton(3), LOG_ODDS_MISS, Clamp::OCTOMAP);
        assert_eq!(tree.leaves().len(), 8);
    }
    assert!(tree.leaf_values.items.len() <= 1, "{:?}", tree.leaf_values);
    assert!(tree.finest.items.len() <= 8);
    // The same with a pruned depth-14 node: its eight parents get leaf values.
    let block: Vec<u64> = (0..64).collect();
    for _ in 0..100 {
        tree.update_sorted(&block, 5.0, Clamp::OCTOMAP);
        assert_eq!(tree.leaves().len(), 1);
        tree.update(&Key::from_morton(40), LOG_ODDS_MISS, Clamp::OCTOMAP);
        assert_eq!(tree.leaves().len(), 7 + 8);
        assert_eq!(
            tree.query(&Key::from_morton(40), DEPTH),
            Some(Clamp::OCTOMAP.max + LOG_ODDS_MISS)
        );
        assert_eq!(
            tree.query(&Key::from_morton(0), 15),
            Some(Clamp::OCTOMAP.max)
        );
    }
    assert!(tree.leaf_values.items.len() <= 8, "{:?}", tree.leaf_values);
    assert!(tree.parents.items.len() <= 8);
    assert!(tree.finest.items.len() <= 8);
}
