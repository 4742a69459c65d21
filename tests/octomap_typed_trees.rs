//! OctoMap's other occupancy trees against sigmap, with liboctomap
//! (Debian's liboctomap-dev and g++, which `.ci/run` installs):
//! `OcTreeStamped` and `ColorOcTree` files OctoMap writes are read as their
//! occupancy, and the `ColorOcTree` of `sigmap score --errors FILE.ot`
//! opens in OctoMap's reader (`tests/octomap/typed_trees.cpp`).

use sigmap::mapping::octomap_io::{is_occupied, read_octree};
use sigmap::mapping::{Clamp, Key, Octree};
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

use common::{sigmap_ok, tool_ok};

/// OctoMap's leaves of a typed tree as `tests/octomap/typed_trees.cpp` lists
/// them (`x y z depth bits`, the key of a coarse leaf its centre's), as
/// sigmap's [`Leaf`](sigmap::mapping::Leaf)s: each key the leaf's smallest.
fn octomap_leaves(path: &Path) -> Vec<(Key, u8, u32)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut leaves: Vec<(Key, u8, u32)> = text
        .lines()
        .map(|line| {
            let f: Vec<u32> = line.split(' ').map(|w| w.parse().unwrap()).collect();
            let depth = f[3] as u8;
            let half = if depth < 16 { 1u32 << (15 - depth) } else { 0 };
            let key = Key(std::array::from_fn(|a| (f[a] - half) as u16));
            (key, depth, f[4])
        })
        .collect();
    leaves.sort_by_key(|&(key, depth, _)| (key.0, depth));
    leaves
}

/// `tests/octomap/typed_trees.cpp` built into `dir`.
fn typed_trees_program(dir: &Path) -> PathBuf {
    let exe = dir.join("typed_trees");
    common::build_against_liboctomap("tests/octomap/typed_trees.cpp", &exe);
    exe
}

/// `tree`'s leaves as [`octomap_leaves`] lists them.
fn sigmap_leaves(tree: Octree) -> Vec<(Key, u8, u32)> {
    let mut leaves: Vec<_> = tree
        .leaves()
        .into_iter()
        .map(|l| (l.key, l.depth, l.value.to_bits()))
        .collect();
    leaves.sort_by_key(|&(key, depth, _)| (key.0, depth));
    leaves
}

/// Checks two leaf lists are equal; else names the first difference.
fn same_leaves(ours: &[(Key, u8, u32)], theirs: &[(Key, u8, u32)], what: &str) {
    let first = ours.iter().zip(theirs).position(|(a, b)| a != b);
    assert!(
        ours.len() == theirs.len() && first.is_none(),
        "{what}: {} leaves read, OctoMap holds {}; first difference at {first:?}: {:?} against {:?}",
        ours.len(),
        theirs.len(),
        first.map(|i| ours[i]),
        first.map(|i| theirs[i]),
    );
}

/// An `OcTreeStamped` and a `ColorOcTree` that OctoMap built and wrote (a
/// scan of a bumpy wall, every leaf of the colour tree coloured) are read as
/// OctoMap holds them: every leaf, depth and log-odds of the `.ot`, and from
/// the `.bt` every leaf at the clamp bound of its class.
#[test]
#[ignore = "needs OctoMap's library (apt-get install liboctomap-dev) and g++; .ci/run runs it"]
fn octomaps_stamped_and_colour_trees_are_read_leaf_for_leaf() {
    let dir = tempfile::tempdir().unwrap();
    let exe = typed_trees_program(dir.path());
    tool_ok(Command::new(&exe).arg("0.02").arg(dir.path()));
    for stem in ["stamped", "colour"] {
        let theirs = octomap_leaves(&dir.path().join(format!("{stem}.leaves")));
        assert!(theirs.len() > 1000, "{stem}: {} leaves", theirs.len());
        let ot = read_octree(&dir.path().join(format!("{stem}.ot")), Clamp::OCTOMAP).unwrap();
        same_leaves(&sigmap_leaves(ot), &theirs, &format!("{stem}.ot"));
        let bt = read_octree(&dir.path().join(format!("{stem}.bt")), Clamp::OCTOMAP).unwrap();
        let classes: Vec<_> = theirs
            .iter()
            .map(|&(key, depth, bits)| {
                let bound = if is_occupied(f32::from_bits(bits)) {
                    Clamp::OCTOMAP.max
                } else {
                    Clamp::OCTOMAP.min
                };
                (key, depth, bound.to_bits())
            })
            .collect();
        same_leaves(&sigmap_leaves(bt), &classes, &format!("{stem}.bt"));
    }
}

/// `sigmap score --errors FILE.ot` writes a `ColorOcTree` that OctoMap's
/// reader opens (`typed_trees list`): one finest occupied leaf per cell of
/// the `.csv` list, red where it is false-free and orange where it is
/// false-occupied.
#[test]
#[ignore = "needs OctoMap's library (apt-get install liboctomap-dev) and g++; .ci/run runs it"]
fn the_errors_colour_tree_opens_in_octomaps_reader() {
    let dir = tempfile::tempdir().unwrap();
    let exe = typed_trees_program(dir.path());
    let map = dir.path().join("map.ot");
    common::quickstart_ray_update_map(&map);
    let (ot, csv) = (dir.path().join("wrong.ot"), dir.path().join("wrong.csv"));
    for errors in [&ot, &csv] {
        let (map, errors) = (map.to_str().unwrap(), errors.to_str().unwrap());
        sigmap_ok(&[
            "score",
            map,
            "experiments/quickstart.toml",
            "-q",
            "--errors",
            errors,
        ]);
    }
    let listed = tool_ok(Command::new(&exe).arg("list").arg(&ot));
    let mut theirs: Vec<Vec<u32>> = listed
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| l.split(' ').map(|w| w.parse().unwrap()).collect())
        .collect();
    theirs.sort_unstable();
    let geometry = Octree::new(0.01);
    let mut ours: Vec<Vec<u32>> = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let centre = std::array::from_fn(|a| f[a].parse::<f64>().unwrap());
            let key = geometry.key(&centre.into()).unwrap();
            let colour = if f[3] == "false_free" {
                [220, 30, 30]
            } else {
                [245, 150, 20]
            };
            let [x, y, z] = key.0.map(u32::from);
            vec![
                x,
                y,
                z,
                16,
                Clamp::OCTOMAP.max.to_bits(),
                colour[0],
                colour[1],
                colour[2],
            ]
        })
        .collect();
    ours.sort_unstable();
    assert!(ours.len() > 100, "{} wrong cells", ours.len());
    assert_eq!(
        theirs.len(),
        ours.len(),
        "leaves OctoMap reads, cells listed"
    );
    let first = theirs.iter().zip(&ours).position(|(a, b)| a != b);
    assert!(
        first.is_none(),
        "first difference: {:?}",
        first.map(|i| (&theirs[i], &ours[i]))
    );
}
