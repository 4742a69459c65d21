use super::*;
use crate::mapping::octree::{Key, LOG_ODDS_HIT, LOG_ODDS_MISS};
use rand::{Rng, SeedableRng};

/// A tree with free space, occupied clusters and pruned blocks.
pub(crate) fn sample_tree() -> Octree {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut tree = Octree::new(0.05);
    for _ in 0..3000 {
        let key = Key([
            32760 + rng.random_range(0..24),
            32760 + rng.random_range(0..24),
            32766 + rng.random_range(0..6),
        ]);
        let delta = if key.0[2] > 32769 {
            LOG_ODDS_HIT
        } else {
            LOG_ODDS_MISS
        };
        tree.update(&key, delta, Clamp::OCTOMAP);
    }
    tree.update_region(
        &Key([32000, 32000, 32000]),
        12,
        LOG_ODDS_MISS,
        Clamp::OCTOMAP,
    );
    tree
}

#[test]
fn ot_round_trip_is_identical() {
    let tree = sample_tree();
    let bytes = to_ot(&tree);
    let back = parse(&bytes, Clamp::OCTOMAP).unwrap();
    assert_eq!(back, tree);
    assert_eq!(to_ot(&back), bytes);
    assert!(String::from_utf8_lossy(&bytes[..200]).contains("id OcTree\nsize "));
}

#[test]
fn bt_round_trip_gives_the_maximum_likelihood_tree() {
    let tree = sample_tree();
    let bytes = to_bt(&tree, Clamp::OCTOMAP);
    let back = parse(&bytes, Clamp::OCTOMAP).unwrap();
    let mut ml = tree.clone();
    ml.map_values(|v| {
        if is_occupied(v) {
            Clamp::OCTOMAP.max
        } else {
            Clamp::OCTOMAP.min
        }
    });
    assert_eq!(back, ml);
    assert_eq!(to_bt(&back, Clamp::OCTOMAP), bytes);
    // Maximum likelihood prunes further than the full tree.
    assert!(ml.stats().nodes <= tree.stats().nodes);
}

#[test]
fn single_leaf_and_empty_trees() {
    let empty = Octree::new(0.1);
    assert_eq!(parse(&to_ot(&empty), Clamp::OCTOMAP).unwrap(), empty);
    assert_eq!(
        parse(&to_bt(&empty, Clamp::OCTOMAP), Clamp::OCTOMAP).unwrap(),
        empty
    );
    let mut whole = Octree::new(0.1);
    whole.update_region(&Key([0, 0, 0]), 0, 1.0, Clamp::OCTOMAP);
    let back = parse(&to_bt(&whole, Clamp::OCTOMAP), Clamp::OCTOMAP).unwrap();
    assert_eq!(back.query(&Key([123, 4, 5]), 16), Some(Clamp::OCTOMAP.max));
}

#[test]
fn corrupt_files_are_rejected() {
    let bytes = to_ot(&sample_tree());
    assert!(parse(&bytes[..bytes.len() - 3], Clamp::OCTOMAP)
        .unwrap_err()
        .contains("ends early"));
    let text = String::from_utf8_lossy(&bytes).replacen("size ", "size 1", 1);
    assert!(parse(text.as_bytes(), Clamp::OCTOMAP).is_err());
    assert!(parse(b"hello\n", Clamp::OCTOMAP)
        .unwrap_err()
        .contains("not an OctoMap file"));
    // Binary bytes where the header's text should be are named as such.
    let error = parse(&[0xff, 0xfe, 0x00, b'\n'], Clamp::OCTOMAP).unwrap_err();
    assert_eq!(error, "not an OctoMap file (its first line is not text)");
    let mut bad = b"# Octomap OcTree file\n".to_vec();
    bad.extend_from_slice(&[0xc3, 0x28, b'\n']);
    let error = parse(&bad, Clamp::OCTOMAP).unwrap_err();
    assert_eq!(error, "a header line before `data` is not text");
    assert_eq!(
        parse(b"# Octomap OcTree file\nid OcTree\n", Clamp::OCTOMAP).unwrap_err(),
        "no `data` line"
    );
}

#[test]
fn a_tree_deeper_than_sixteen_levels_is_refused() {
    // A chain of nodes, each with one child: 17 levels of children.
    for levels in [16usize, 17] {
        for binary in [false, true] {
            let mut bytes =
                header(if binary { BT_HEADER } else { OT_HEADER }, levels + 1, 0.1).into_bytes();
            for depth in 0..=levels {
                if binary {
                    // Child 0 inner (code 3) above the last level, free (1) at it.
                    if depth < levels {
                        bytes.extend_from_slice(&[if depth + 1 < levels { 3 } else { 1 }, 0]);
                    }
                } else {
                    bytes.extend_from_slice(&0.5f32.to_le_bytes());
                    bytes.push(u8::from(depth < levels));
                }
            }
            let read = parse(&bytes, Clamp::OCTOMAP);
            if levels == 16 {
                let tree = read.unwrap_or_else(|e| panic!("16 levels, binary {binary}: {e}"));
                assert_eq!(tree.stats().leaves, 1);
            } else {
                assert!(
                    read.as_ref()
                        .is_err_and(|e| e.contains("below the finest level")),
                    "17 levels, binary {binary}: {:?}",
                    read.map(|t| t.stats())
                );
            }
        }
    }
}

#[test]
fn a_header_with_a_resolution_that_is_no_number_is_refused() {
    for res in ["inf", "-inf", "NaN", "0", "-0.1", "1e400"] {
        let bytes = format!("# Octomap OcTree binary file\nid OcTree\nsize 0\nres {res}\ndata\n");
        let error = parse(bytes.as_bytes(), Clamp::OCTOMAP).unwrap_err();
        assert!(error.contains("res"), "{res}: {error}");
    }
}

#[test]
fn a_depth_15_inner_node_reads_as_the_maximum_of_its_cells() {
    // One cell: sixteen inner nodes (value, mask) above one finest leaf.
    let mut tree = Octree::new(0.05);
    let key = Key([32768, 32768, 32768]);
    tree.update(&key, LOG_ODDS_HIT, Clamp::OCTOMAP);
    let bytes = to_ot(&tree);
    let data = bytes.len() - (16 * 5 + 5);
    // A file whose depth-15 node says 9.0 (OctoMap writes its children's
    // maximum there): sigmap keeps the maximum, as its own tree holds it.
    let mut edited = bytes.clone();
    let at = data + 15 * 5;
    assert_eq!(edited[at..at + 4], LOG_ODDS_HIT.to_le_bytes());
    edited[at..at + 4].copy_from_slice(&9.0f32.to_le_bytes());
    let back = parse(&edited, Clamp::OCTOMAP).unwrap();
    assert_eq!(back.query(&key, 15), Some(LOG_ODDS_HIT));
    assert_eq!(back, tree);
    assert_eq!(to_ot(&back), bytes);
}

/// A file's header (through its `data` line) and its body.
fn split_header(bytes: &[u8]) -> (String, &[u8]) {
    let data = bytes.windows(5).position(|w| w == b"data\n").unwrap() + 5;
    let (head, body) = bytes.split_at(data);
    (String::from_utf8(head.to_vec()).unwrap(), body)
}

/// `.ot` body bytes with `extra` bytes (0x7f, 0x80, 0x81, …) after each
/// node's log-odds, as a tree whose nodes carry more than a value writes them.
fn with_node_extras(body: &[u8], extra: usize) -> Vec<u8> {
    fn node(body: &[u8], at: &mut usize, extra: usize, out: &mut Vec<u8>) {
        out.extend_from_slice(&body[*at..*at + 4]);
        out.extend((0..extra).map(|k| 0x7f + k as u8));
        let mask = body[*at + 4];
        out.push(mask);
        *at += 5;
        for _ in 0..mask.count_ones() {
            node(body, at, extra, out);
        }
    }
    let mut out = Vec::new();
    let mut at = 0;
    node(body, &mut at, extra, &mut out);
    assert_eq!(at, body.len(), "one tree");
    out
}

/// The `.ot` and `.bt` files of OctoMap's other occupancy trees give the
/// same occupancy: `OcTreeStamped` (no time stamp is written) and
/// `ColorOcTree` (three colour bytes after each node's log-odds). Other
/// tree types are refused by name.
#[test]
fn stamped_and_colour_trees_are_read_as_their_occupancy() {
    let tree = sample_tree();
    let ot = to_ot(&tree);
    let (head, body) = split_header(&ot);
    for (id, extra) in [("OcTreeStamped", 0), ("ColorOcTree", 3)] {
        let mut typed = head
            .replace("id OcTree\n", &format!("id {id}\n"))
            .into_bytes();
        typed.extend(with_node_extras(body, extra));
        let back = parse(&typed, Clamp::OCTOMAP).unwrap_or_else(|e| panic!("{id}: {e}"));
        assert_eq!(back, tree, "{id}");
        assert_eq!(to_ot(&back), ot, "{id}");
        let bt = to_bt(&tree, Clamp::OCTOMAP);
        let (bt_head, bt_body) = split_header(&bt);
        let mut typed_bt = bt_head
            .replace("id OcTree\n", &format!("id {id}\n"))
            .into_bytes();
        typed_bt.extend_from_slice(bt_body);
        let back = parse(&typed_bt, Clamp::OCTOMAP).unwrap();
        assert_eq!(to_bt(&back, Clamp::OCTOMAP), bt, "{id} .bt");
    }
    // A colour tree's extra bytes read as a plain tree's are refused.
    let mut wrong = head.clone().into_bytes();
    wrong.extend(with_node_extras(body, 3));
    assert!(parse(&wrong, Clamp::OCTOMAP).is_err());
    let mut counting = head
        .replace("id OcTree\n", "id CountingOcTree\n")
        .into_bytes();
    counting.extend_from_slice(body);
    let error = parse(&counting, Clamp::OCTOMAP).unwrap_err();
    assert!(
        error.contains("`CountingOcTree`") && error.contains("OcTree, OcTreeStamped, ColorOcTree"),
        "{error}"
    );
    let mut no_id = head.replace("id OcTree\n", "").into_bytes();
    no_id.extend_from_slice(body);
    let error = parse(&no_id, Clamp::OCTOMAP).unwrap_err();
    assert!(error.contains("no `id` line"), "{error}");
}

/// A colour tree's leaves as its `.ot` body lists them: `(Morton code of the
/// leaf's smallest cell, depth, log-odds, colour)`, depth first.
fn colour_leaves(body: &[u8]) -> Vec<(u64, u8, f32, [u8; 3])> {
    fn node(
        body: &[u8],
        at: &mut usize,
        code: u64,
        depth: u8,
        out: &mut Vec<(u64, u8, f32, [u8; 3])>,
    ) {
        let value = f32::from_le_bytes(body[*at..*at + 4].try_into().unwrap());
        let colour = [body[*at + 4], body[*at + 5], body[*at + 6]];
        let mask = body[*at + 7];
        *at += 8;
        if mask == 0 {
            out.push((code, depth, value, colour));
        }
        for child in 0..8u64 {
            if mask & 1 << child != 0 {
                let shift = 3 * (u32::from(DEPTH) - u32::from(depth) - 1);
                node(body, at, code | child << shift, depth + 1, out);
            }
        }
    }
    let mut out = Vec::new();
    let mut at = 0;
    node(body, &mut at, 0, 0, &mut out);
    assert_eq!(at, body.len(), "one tree");
    out
}

/// `colour_cells_to_ot` writes every cell as its own leaf in its colour,
/// siblings of one colour included (none pruned), under white inner nodes:
/// read back by sigmap's reader as the cells at the value, and with their
/// colours by a walk of the body.
#[test]
fn colour_cells_are_written_each_a_leaf_in_its_colour() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let mut cells: Vec<(u64, [u8; 3])> = (0..500)
        .map(|_| {
            let key = Key([
                32760 + rng.random_range(0..8),
                32760 + rng.random_range(0..8),
                32766 + rng.random_range(0..4),
            ]);
            let colour = if rng.random_bool(0.5) {
                [220, 30, 30]
            } else {
                [245, 150, 20]
            };
            (key.morton(), colour)
        })
        .collect();
    // Eight siblings of one colour: a tree would prune them.
    let base = Key([32000, 32000, 32000]).morton();
    cells.extend((0..8).map(|child| (base | child, [1, 2, 3])));
    cells.sort_unstable_by_key(|c| c.0);
    cells.dedup_by_key(|c| c.0);
    let bytes = colour_cells_to_ot(0.05, &cells, 3.5, "# a comment\n");
    let (head, body) = split_header(&bytes);
    assert!(
        head.starts_with("# Octomap OcTree file\n# a comment\n"),
        "{head}"
    );
    assert!(head.contains("id ColorOcTree\n"), "{head}");
    let listed = colour_leaves(body);
    let expected: Vec<_> = cells
        .iter()
        .map(|&(code, colour)| (code, DEPTH, 3.5, colour))
        .collect();
    assert_eq!(listed, expected);
    let tree = parse(&bytes, Clamp::OCTOMAP).unwrap();
    let mut leaves: Vec<_> = tree
        .leaves()
        .into_iter()
        .map(|l| (l.key.morton(), l.depth, l.value))
        .collect();
    leaves.sort_unstable_by_key(|l| l.0);
    let expected: Vec<_> = cells.iter().map(|&(code, _)| (code, DEPTH, 3.5)).collect();
    assert_eq!(leaves, expected);
    // No cells: an empty tree.
    let empty = colour_cells_to_ot(0.05, &[], 3.5, "");
    assert_eq!(parse(&empty, Clamp::OCTOMAP).unwrap(), Octree::new(0.05));
}
