//! Ground-truth occupancy of a scene (docs/math.md §7.1).
//!
//! Rule: a cell of the finest level is **occupied** when its box meets a
//! solid in more than a face (the box shrunk by [`TOUCH`] on every side
//! meets its surface or interior) and **free** otherwise; cells whose centre
//! lies outside the scene's workspace are not part of the truth (unknown). A
//! cell that only touches a face is therefore free, whatever the rounding. Occupied cells hold OctoMap's clamp maximum, free ones its
//! minimum, so the truth is itself an OctoMap tree.
//!
//! The voxelisation recurses over octree cells: a cell inside the workspace
//! that no object's bounding box meets is free as a whole (one coarse leaf);
//! only cells near objects are split down to the finest level, where the
//! exact box–solid test decides.

use crate::geometry::{Isometry3, Matrix3, Point3, Vector3};
use crate::mapping::octree::{Clamp, Key, DEPTH};
use crate::mapping::Octree;
use crate::sim::scene::{Bounds, Scene};

/// How far (m) a solid must reach into a cell to occupy it: faces that only
/// touch a cell (or lie within 0.1 µm of its side) leave it free.
pub const TOUCH: f64 = 1e-7;

/// The true occupancy of `scene`'s workspace at `resolution`.
pub fn voxelise(scene: &Scene, resolution: f64) -> Octree {
    voxelise_at(scene, resolution, &Vector3::zeros())
}

/// The true occupancy in the map frame `map = scene + offset` (the grid's
/// sub-voxel offset of `Experiment::map_offset`).
pub fn voxelise_at(scene: &Scene, resolution: f64, offset: &Vector3) -> Octree {
    voxelise_in(
        scene,
        resolution,
        &Isometry3::translation(offset.x, offset.y, offset.z),
    )
}

/// The true occupancy in the map frame `map = map_from_scene · scene`, any
/// rigid placement: the scene as a registration error moves it, for example
/// (`runner::registered_truth`). The same rule cell by cell, each cell's box
/// taken into the scene frame.
pub fn voxelise_in(scene: &Scene, resolution: f64, map_from_scene: &Isometry3) -> Octree {
    voxelise_within(scene, resolution, map_from_scene, &KeyBox::ALL)
}

/// [`voxelise_in`] over the finest cells of `region` only: the same value
/// on each of them, every other cell unknown. A run's truth is needed only
/// over its observable cells, so its cost follows the observed volume and
/// the surfaces in it, not the workspace (whose boundary alone holds
/// (area / resolution²) cells).
pub fn voxelise_within(
    scene: &Scene,
    resolution: f64,
    map_from_scene: &Isometry3,
    region: &KeyBox,
) -> Octree {
    Voxeliser {
        scene,
        known: Placement::new(map_from_scene),
        voters: Voters::Known,
        region: *region,
    }
    .tree(resolution)
}

/// A vote over placements of the scene: each finest cell of `region` that
/// [`voxelise_within`] at `map_from_scene` knows is occupied where at least
/// `needed` of `draws` put a solid in it (each draw's cell decided by the
/// same rule, a draw whose cell centre leaves the workspace not voting for
/// it) and free otherwise; every other cell unknown. The same tree as
/// voxelising each draw and counting, cell by cell, in one recursion over
/// the union of the draws' surfaces instead of one per draw: a block is
/// decided whole when enough draws hold it inside a solid, or too few meet
/// a solid at all (`registration_belief`, docs/math.md §7.5).
pub fn voxelise_votes(
    scene: &Scene,
    resolution: f64,
    map_from_scene: &Isometry3,
    draws: &[Isometry3],
    needed: usize,
    region: &KeyBox,
) -> Octree {
    Voxeliser {
        scene,
        known: Placement::new(map_from_scene),
        voters: Voters::Draws {
            placements: draws.iter().map(Placement::new).collect(),
            needed,
        },
        region: *region,
    }
    .tree(resolution)
}

/// A box of finest cells, by key, bounds included.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyBox {
    min: [u16; 3],
    max: [u16; 3],
}

impl KeyBox {
    /// Every cell of the tree.
    pub const ALL: KeyBox = KeyBox {
        min: [0; 3],
        max: [u16::MAX; 3],
    };

    /// The smallest box that holds `cells` (Morton codes; an empty box
    /// without any).
    pub fn spanning(cells: impl IntoIterator<Item = u64>) -> KeyBox {
        let mut span = KeyBox {
            min: [u16::MAX; 3],
            max: [0; 3],
        };
        let mut any = false;
        for code in cells {
            let key = Key::from_morton(code);
            for k in 0..3 {
                span.min[k] = span.min[k].min(key.0[k]);
                span.max[k] = span.max[k].max(key.0[k]);
            }
            any = true;
        }
        if any {
            span
        } else {
            KeyBox {
                min: [1; 3],
                max: [0; 3],
            }
        }
    }

    /// The box's corners in the frame of `tree` (its lowest cell's lower
    /// corner, its highest cell's upper one); `None` for an empty box.
    pub fn corners(&self, tree: &Octree) -> Option<(Point3, Point3)> {
        (0..3).all(|k| self.min[k] <= self.max[k]).then(|| {
            (
                tree.lattice_point(&Key(self.min), [0; 3]),
                tree.lattice_point(&Key(self.max), [1; 3]),
            )
        })
    }

    /// The key range `[first, last]` on each axis of the cell at `depth`.
    fn range(key: &Key, depth: u8) -> ([u16; 3], [u16; 3]) {
        let span = (1u32 << (DEPTH - depth)) - 1;
        let last = key.0.map(|k| (u32::from(k) + span) as u16);
        (key.0, last)
    }

    /// Whether the cell at `depth` shares a finest cell with the box.
    fn meets(&self, key: &Key, depth: u8) -> bool {
        let (first, last) = Self::range(key, depth);
        (0..3).all(|k| first[k] <= self.max[k] && self.min[k] <= last[k])
    }

    /// Whether every finest cell of the cell at `depth` is in the box.
    pub fn holds(&self, key: &Key, depth: u8) -> bool {
        let (first, last) = Self::range(key, depth);
        (0..3).all(|k| self.min[k] <= first[k] && last[k] <= self.max[k])
    }
}

/// Finest cells of a tree that are occupied and free (OctoMap's threshold).
pub fn cell_counts(tree: &Octree) -> (u64, u64) {
    let (mut occupied, mut free) = (0u64, 0u64);
    tree.visit_leaves(|leaf| {
        let cells = 1u64 << (3 * (DEPTH - leaf.depth) as u64);
        if crate::mapping::octomap_io::is_occupied(leaf.value) {
            occupied += cells;
        } else {
            free += cells;
        }
    });
    (occupied, free)
}

/// Where the map's cells lie in the scene, computed once per voxelisation:
/// `scene_from_map`, and `|R|` of its rotation, the reach of a cell along
/// each scene axis per unit of half-edge.
struct Placement {
    scene_from_map: Isometry3,
    reach: Matrix3,
}

impl Placement {
    fn new(map_from_scene: &Isometry3) -> Self {
        let scene_from_map = map_from_scene.inverse();
        let reach = scene_from_map.rotation.to_rotation_matrix().matrix().abs();
        Self {
            scene_from_map,
            reach,
        }
    }

    /// The frame of `cell` (placed by this placement) in the scene: its
    /// centre, turned as the map is.
    fn scene_from_cell(&self, cell: &SceneCell) -> Isometry3 {
        Isometry3::from_parts(cell.centre.coords.into(), self.scene_from_map.rotation)
    }

    /// The cell in the scene frame.
    fn cell(&self, tree: &Octree, key: &Key, depth: u8) -> SceneCell {
        let centre = self.scene_from_map * tree.center(key, depth);
        let half = tree.node_size(depth) / 2.0;
        let reach = self.reach * Vector3::repeat(half);
        SceneCell {
            centre,
            half,
            bounds: Bounds {
                min: centre - reach,
                max: centre + reach,
            },
        }
    }
}

/// A cell in the scene frame: its centre, half-edge, and the axis-aligned
/// box that holds it (the cell itself when the placement has no rotation).
struct SceneCell {
    centre: Point3,
    half: f64,
    bounds: Bounds,
}

/// What one voxelisation decides cells with: the scene, where the map's
/// cells lie in it (`known`: which cells the tree knows), who votes on
/// their occupancy, and the cells wanted.
struct Voxeliser<'a> {
    scene: &'a Scene,
    known: Placement,
    voters: Voters,
    region: KeyBox,
}

/// Who decides a cell's occupancy.
enum Voters {
    /// The known placement alone: the truth as it places the scene.
    Known,
    /// Occupied where at least `needed` of `placements` put a solid.
    Draws {
        placements: Vec<Placement>,
        needed: usize,
    },
}

/// How a block of cells is called as a whole, if it can be.
enum Block {
    Free,
    Occupied,
    Split,
}

impl Voxeliser<'_> {
    /// The tree at `resolution`, decided from the root down.
    fn tree(&self, resolution: f64) -> Octree {
        let mut tree = Octree::new(resolution);
        self.recurse(&mut tree, Key([0, 0, 0]), 0);
        tree
    }

    fn recurse(&self, tree: &mut Octree, key: Key, depth: u8) {
        let (scene, region) = (self.scene, &self.region);
        if !region.meets(&key, depth) {
            return;
        }
        let cell = self.known.cell(tree, &key, depth);
        let ws = &scene.workspace;
        if !cell.bounds.intersects(ws) {
            return;
        }
        let clamp = Clamp::OCTOMAP;
        if depth == DEPTH {
            if !ws.contains(&cell.centre) {
                return;
            }
            let occupied = match &self.voters {
                Voters::Known => self.holds_solid(&self.known, &cell),
                Voters::Draws { placements, needed } => {
                    let votes = placements
                        .iter()
                        .filter(|p| {
                            let drawn = p.cell(tree, &key, depth);
                            ws.contains(&drawn.centre) && self.holds_solid(p, &drawn)
                        })
                        .count();
                    votes >= *needed
                }
            };
            tree.update(&key, if occupied { clamp.max } else { clamp.min }, clamp);
            return;
        }
        let (min, max) = (cell.bounds.min, cell.bounds.max);
        if ws.contains(&min) && ws.contains(&max) && region.holds(&key, depth) {
            // A block no solid comes near is free as a whole, one that lies
            // inside a solid occupied as a whole: the tree grows with the
            // surfaces, not with the volumes they enclose.
            let value = match self.block(tree, &key, depth, &cell) {
                Block::Free => Some(clamp.min),
                Block::Occupied => Some(clamp.max),
                Block::Split => None,
            };
            if let Some(value) = value {
                tree.update_region(&key, depth, value, clamp);
                return;
            }
        }
        let bit = 15 - depth as u32;
        for child in 0..8u16 {
            let mut k = key;
            for (axis, kk) in k.0.iter_mut().enumerate() {
                *kk |= ((child >> axis) & 1) << bit;
            }
            self.recurse(tree, k, depth + 1);
        }
    }

    /// Whether the finest cell `cell` (in the scene frame as `placement`
    /// puts it) meets a solid in more than a face.
    fn holds_solid(&self, placement: &Placement, cell: &SceneCell) -> bool {
        let scene = self.scene;
        let scene_from_cell = placement.scene_from_cell(cell);
        let half = Vector3::repeat(cell.half - TOUCH);
        scene
            .objects_near(&cell.bounds.min, &cell.bounds.max)
            .into_iter()
            .any(|o| scene.box_meets_object(o, &scene_from_cell, &half))
    }

    /// How the block `cell` (inside the workspace and the region, as the
    /// known placement puts it) is called as a whole.
    fn block(&self, tree: &Octree, key: &Key, depth: u8, cell: &SceneCell) -> Block {
        // Per placement: whether a solid comes near the block, and whether
        // the block lies inside one (and inside the workspace, so that each
        // of its cells votes).
        let reach = |placement: &Placement, cell: &SceneCell| -> (bool, bool) {
            let scene = self.scene;
            let ws = &scene.workspace;
            let near = scene.objects_near(&cell.bounds.min, &cell.bounds.max);
            if near.is_empty() {
                return (false, false);
            }
            let scene_from_cell = placement.scene_from_cell(cell);
            let half = Vector3::repeat(cell.half);
            let within = ws.contains(&cell.bounds.min) && ws.contains(&cell.bounds.max);
            let inside = within
                && near
                    .iter()
                    .any(|&o| scene.box_inside_object(o, &scene_from_cell, &half));
            (true, inside)
        };
        let (meet, inside, needed) = match &self.voters {
            Voters::Known => {
                let (near, inside) = reach(&self.known, cell);
                (usize::from(near), usize::from(inside), 1)
            }
            Voters::Draws { placements, needed } => {
                let (mut meet, mut inside) = (0, 0);
                for p in placements {
                    let (near, holds) = reach(p, &p.cell(tree, key, depth));
                    meet += usize::from(near);
                    inside += usize::from(holds);
                }
                (meet, inside, *needed)
            }
        };
        if meet < needed {
            Block::Free
        } else if inside >= needed {
            Block::Occupied
        } else {
            Block::Split
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::octomap_io::is_occupied;
    use std::path::PathBuf;

    fn scene(body: &str) -> (tempfile::TempDir, Scene) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(
            &path,
            format!("[workspace]\nmin = [-0.5, -0.5, -0.5]\nmax = [0.5, 0.5, 0.5]\n{body}"),
        )
        .unwrap();
        let scene = Scene::load(&path).unwrap();
        (dir, scene)
    }

    #[test]
    fn faces_on_cell_planes_leave_the_touching_cells_free_and_offsets_move_the_truth() {
        // A 0.2 m cube whose faces lie exactly on 5 cm cell planes: 4 cells a side.
        let (_d, s) =
            scene("[[object]]\nshape = \"box\"\nsize = [0.2, 0.2, 0.2]\nxyz = [0.1, 0.1, 0.1]\n");
        let truth = voxelise(&s, 0.05);
        assert_eq!(cell_counts(&truth).0, 4 * 4 * 4);
        // A sub-voxel offset puts the faces inside cells: 5 a side.
        let shifted = voxelise_at(&s, 0.05, &Vector3::new(0.01, 0.02, 0.03));
        assert_eq!(cell_counts(&shifted).0, 5 * 5 * 5);
        // A whole-cell offset moves the truth by one cell.
        let moved = voxelise_at(&s, 0.05, &Vector3::new(0.05, 0.0, 0.0));
        assert_eq!(cell_counts(&moved).0, 4 * 4 * 4);
        let at = |t: &Octree, x: f64| t.value_at(&Point3::new(x, 0.1, 0.1)).map(is_occupied);
        assert_eq!(at(&truth, 0.025), Some(true));
        assert_eq!(at(&moved, 0.025), Some(false));
        assert_eq!(at(&moved, 0.225), Some(true));
    }

    #[test]
    fn a_placed_scene_is_the_scene_with_its_solids_moved() {
        // Voxelising scene A placed by a rotation about z and a translation
        // equals voxelising scene B, whose solids were moved the same way.
        let (theta, t) = (0.3f64, Vector3::new(0.013, -0.027, 0.0071));
        let (c, s) = (theta.cos(), theta.sin());
        let solid = |x: f64, y: f64, z: f64, yaw: f64| {
            format!(
                "[[object]]\nshape = \"box\"\nsize = [0.17, 0.09, 0.13]\n\
                 xyz = [{x}, {y}, {z}]\nrpy = [0.0, 0.0, {yaw}]\n"
            )
        };
        let (p, q) = ([0.1, 0.05, 0.02], [-0.12, -0.1, 0.07]);
        let moved = |v: [f64; 3]| {
            [
                c * v[0] - s * v[1] + t.x,
                s * v[0] + c * v[1] + t.y,
                v[2] + t.z,
            ]
        };
        let (_a, a) = scene(&(solid(p[0], p[1], p[2], 0.0) + &solid(q[0], q[1], q[2], 0.0)));
        let (pm, qm) = (moved(p), moved(q));
        let (_b, b) =
            scene(&(solid(pm[0], pm[1], pm[2], theta) + &solid(qm[0], qm[1], qm[2], theta)));
        let placement = Isometry3::new(t, Vector3::z() * theta);
        let (placed, direct) = (voxelise_in(&a, 0.02, &placement), voxelise(&b, 0.02));
        let mut occupied = 0;
        for i in -15..15 {
            for j in -15..15 {
                for k in -10..12 {
                    let x =
                        Point3::new(i as f64, j as f64, k as f64) * 0.02 + Vector3::repeat(0.01);
                    let call = |tree: &Octree| tree.value_at(&x).map(is_occupied);
                    assert_eq!(call(&placed), call(&direct), "{x:?}");
                    occupied += usize::from(call(&direct) == Some(true));
                }
            }
        }
        assert!(occupied > 300, "{occupied}");
    }

    #[test]
    fn a_vote_over_placements_is_each_placement_voxelised_and_counted() {
        // A large box (whole blocks inside it), a sphere and a box by the
        // workspace's edge (draws push their cells and blocks out), a slanted cylinder; six draws a
        // few cells apart. Every cell's call is the count, over the draws
        // voxelised one by one, of those that occupy it, against `needed`;
        // the cells the known placement does not know stay unknown.
        let (_d, s) = scene(
            "[[object]]\nshape = \"box\"\nsize = [0.5, 0.4, 0.3]\nxyz = [-0.1, 0.0, -0.1]\n\
             [[object]]\nshape = \"sphere\"\nradius = 0.1\nxyz = [0.41, 0.3, 0.35]\n\
             [[object]]\nshape = \"box\"\nsize = [0.4, 0.4, 0.4]\nxyz = [0.45, -0.1, -0.25]\n\
             [[object]]\nshape = \"cylinder\"\nradius = 0.05\nheight = 0.3\nxyz = [0.3, -0.3, 0.2]\nrpy = [0.4, 0.2, 0.0]\n",
        );
        let known = Isometry3::new(
            Vector3::new(0.003, -0.006, 0.011),
            Vector3::new(0.0, 0.0, 0.02),
        );
        let draws: Vec<Isometry3> = (0..6)
            .map(|k| {
                let f = k as f64 - 2.5;
                known
                    * Isometry3::new(
                        Vector3::new(0.03 * f, -0.009 * f, 0.017 * (f * 1.7).sin()),
                        Vector3::new(0.02 * (f * 0.9).cos(), 0.015 * f, -0.01 * f),
                    )
            })
            .collect();
        let one_by_one: Vec<Octree> = draws.iter().map(|d| voxelise_in(&s, 0.02, d)).collect();
        let truth = voxelise_in(&s, 0.02, &known);
        for needed in [1, 3, 6] {
            let votes = voxelise_votes(&s, 0.02, &known, &draws, needed, &KeyBox::ALL);
            let (mut occupied, mut split) = (0, 0);
            for i in -26..26 {
                for j in -26..26 {
                    for k in -26..26 {
                        let x = Point3::new(i as f64, j as f64, k as f64) * 0.02
                            + Vector3::repeat(0.01);
                        if truth.value_at(&x).is_none() {
                            assert_eq!(votes.value_at(&x), None, "{x:?}");
                            continue;
                        }
                        let count = one_by_one
                            .iter()
                            .filter(|t| t.value_at(&x).is_some_and(is_occupied))
                            .count();
                        let call = votes.value_at(&x).map(is_occupied);
                        assert_eq!(call, Some(count >= needed), "{x:?}, needed {needed}");
                        occupied += usize::from(count >= needed);
                        split += usize::from(count > 0 && count < 6);
                    }
                }
            }
            assert!(occupied > 2000 && split > 500, "{occupied} {split}");
        }
        // Every draw the known placement: the truth, leaf for leaf.
        let same = voxelise_votes(&s, 0.02, &known, &[known; 4], 2, &KeyBox::ALL);
        assert_eq!(same.leaves(), truth.leaves());
    }

    #[test]
    fn every_cell_a_solid_meets_is_occupied_and_the_rest_free() {
        // A 0.2 m cube off the 5 cm grid spans 5 cells per axis.
        let (_d, s) = scene(
            "[[object]]\nshape = \"box\"\nsize = [0.2, 0.2, 0.2]\nxyz = [0.113, 0.087, 0.1042]\n",
        );
        let truth = voxelise(&s, 0.05);
        let (occupied, free) = cell_counts(&truth);
        assert_eq!(occupied, 5 * 5 * 5);
        assert_eq!(
            occupied + free,
            20 * 20 * 20,
            "every workspace cell is decided"
        );
        // An off-grid sphere: occupied cells cover it, and their count exceeds its volume.
        let (_d, s) =
            scene("[[object]]\nshape = \"sphere\"\nradius = 0.2\nxyz = [0.013, -0.021, 0.007]\n");
        let truth = voxelise(&s, 0.02);
        let (cells, _) = cell_counts(&truth);
        let volume = cells as f64 * 0.02f64.powi(3);
        let sphere = 4.0 / 3.0 * std::f64::consts::PI * 0.2f64.powi(3);
        assert!(
            volume > sphere && volume < 1.35 * sphere,
            "{volume} vs {sphere}"
        );
        for p in [
            Point3::new(0.013, -0.021, 0.007),
            Point3::new(0.2, -0.021, 0.007),
        ] {
            assert!(is_occupied(truth.value_at(&p).unwrap()), "{p:?}");
        }
        assert!(!is_occupied(
            truth.value_at(&Point3::new(0.35, 0.35, 0.35)).unwrap()
        ));
        assert!(
            truth.value_at(&Point3::new(0.7, 0.0, 0.0)).is_none(),
            "outside the workspace"
        );
    }

    #[test]
    fn bunny_interior_and_thin_boards_are_occupied() {
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let shelf = Scene::load(&root.join("shelf.toml")).unwrap();
        let truth = voxelise(&shelf, 0.01);
        // The 1.2 cm upper board and the 1 cm plate are never lost.
        for p in [
            Point3::new(0.15, -0.2, 0.6123),
            Point3::new(0.16, 0.0217, 0.421),
            Point3::new(0.15, 0.0, 0.05),
        ] {
            assert!(is_occupied(truth.value_at(&p).unwrap()), "{p:?}");
        }
        // The 3 cm passage between the plate and the divider stays free in its middle.
        assert!(!is_occupied(
            truth.value_at(&Point3::new(0.16, 0.0415, 0.42)).unwrap()
        ));
        let tabletop = Scene::load(&root.join("tabletop.toml")).unwrap();
        let truth = voxelise(&tabletop, 0.01);
        let bunny = tabletop
            .objects()
            .iter()
            .find(|o| o.kind == "mesh")
            .unwrap()
            .bounds;
        let centre = Point3::from((bunny.min.coords + bunny.max.coords) / 2.0);
        assert!(
            is_occupied(truth.value_at(&centre).unwrap()),
            "the bunny's interior is filled"
        );
    }
}
