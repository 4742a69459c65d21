//! Scenes: TOML files of primitives and meshes, loaded into parry shapes with a
//! BVH for ray casting and point-inside tests.
//!
//! Everything is expressed in the scene frame (the paper's R_scene); the scene
//! is placed in the world by `world_from_scene` (T_sw) in the experiment.

use super::mesh::Mesh;
use crate::error::{read_toml_with, Error, Result};
use crate::geometry::{Isometry3, Point3, Pose, Vector3};
use cylinder::cast_cylinder;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::{Pose as ParryPose, Rotation as ParryRotation, Vector as ParryVector};
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy};
use parry3d_f64::query::Ray;
use parry3d_f64::shape::{SharedShape, TriMesh, TriMeshFlags};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// An axis-aligned box `[min, max]` in the scene frame (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Lower corner.
    pub min: Point3,
    /// Upper corner.
    pub max: Point3,
}

impl Bounds {
    /// The box's edge lengths (m).
    pub fn extent(&self) -> [f64; 3] {
        (self.max - self.min).into()
    }

    /// The length of the box's diagonal (m).
    pub fn diagonal(&self) -> f64 {
        (self.max - self.min).norm()
    }

    /// The largest distance of the box from the origin along any axis (m).
    pub fn reach(&self) -> f64 {
        self.min
            .coords
            .iter()
            .chain(self.max.coords.iter())
            .fold(0.0, |m, v| m.max(v.abs()))
    }
}

impl Bounds {
    /// True when `p` lies inside (boundary included).
    pub fn contains(&self, p: &Point3) -> bool {
        (0..3).all(|k| p[k] >= self.min[k] && p[k] <= self.max[k])
    }

    /// True when the two boxes overlap.
    pub fn intersects(&self, other: &Bounds) -> bool {
        (0..3).all(|k| self.min[k] <= other.max[k] && other.min[k] <= self.max[k])
    }
}

/// One solid of the scene.
#[derive(Clone)]
pub struct SceneObject {
    /// Its name (from the file, or `shape #index`).
    pub name: String,
    /// `box`, `cylinder`, `sphere` or `mesh`.
    pub kind: &'static str,
    /// Number of triangles (0 for analytic primitives).
    pub triangles: usize,
    /// Its bounding box in the scene frame.
    pub bounds: Bounds,
    pose: ParryPose,
    shape: SharedShape,
    /// `(radius, half height)` of a cylinder, cast analytically: parry casts
    /// rays on cylinders by GJK, several times slower than the closed form.
    cylinder: Option<(f64, f64)>,
}

/// How many times the workspace's diagonal a mesh object may span before
/// sigmap asks whether its file is in millimetres
/// ([`Scene::oversized_mesh`]): a floor or a wall may be a few times the
/// workspace, a CAD part in millimetres is a thousand times itself.
pub const MESH_SPAN_RATIO: f64 = 20.0;

/// What to do about a mesh [`Scene::oversized_mesh`] names.
pub const MILLIMETRES: &str = "if its mesh file is in millimetres, give the object `scale = 0.001`";

/// A loaded scene: solids, a BVH over them, and the workspace to map.
pub struct Scene {
    /// The scene's name.
    pub name: String,
    /// The file it came from.
    pub source: PathBuf,
    /// Free text from the file.
    pub description: String,
    /// The region the map covers (and the ground truth voxelises).
    pub workspace: Bounds,
    /// Every file the scene was read from: the scene file, then its meshes.
    pub inputs: Vec<PathBuf>,
    /// What the user should know of the file that is not an error
    /// ([`Scene::notes`]).
    notes: Vec<String>,
    objects: Vec<SceneObject>,
    bvh: Bvh,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: Option<String>,
    #[serde(default)]
    description: String,
    workspace: WorkspaceSpec,
    #[serde(rename = "object", default)]
    objects: Vec<ObjectSpec>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WorkspaceSpec {
    min: [f64; 3],
    max: [f64; 3],
}

#[derive(Deserialize)]
#[serde(untagged, expecting = "scale: a number, or three numbers [x, y, z]")]
enum Scale {
    Uniform(f64),
    PerAxis([f64; 3]),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectSpec {
    name: Option<String>,
    shape: String,
    size: Option<[f64; 3]>,
    radius: Option<f64>,
    height: Option<f64>,
    file: Option<PathBuf>,
    scale: Option<Scale>,
    #[serde(default)]
    xyz: [f64; 3],
    #[serde(default)]
    rpy: [f64; 3],
}

/// nalgebra isometry to parry pose (the one conversion point).
pub(crate) fn to_parry_pose(iso: &Isometry3) -> ParryPose {
    let q = iso.rotation.quaternion();
    let t = iso.translation.vector;
    ParryPose::from_parts(
        ParryVector::new(t.x, t.y, t.z),
        ParryRotation::from_xyzw(q.i, q.j, q.k, q.w),
    )
}

pub(crate) fn to_parry(v: &Vector3) -> ParryVector {
    ParryVector::new(v.x, v.y, v.z)
}

/// The refusal of a primitive's `what` (its field and value) for reaching
/// past [`MAX_MESH_REACH`].
fn past_any_workcell(what: String) -> String {
    format!(
        "{what} is past any workcell: an object lies within {} km of its origin",
        MAX_MESH_REACH / 1000.0
    )
}

/// `value`, a positive length no greater than `limit` (m).
fn positive(
    value: Option<f64>,
    field: &str,
    shape: &str,
    limit: f64,
) -> std::result::Result<f64, String> {
    match value {
        None => Err(format!("a {shape} needs `{field}`")),
        Some(v) if !(v.is_finite() && v > 0.0) => {
            Err(format!("`{field}` = {v} must be a positive length (m)"))
        }
        Some(v) if v > limit => Err(past_any_workcell(format!("`{field}` = {v:e} m"))),
        Some(v) => Ok(v),
    }
}

impl ObjectSpec {
    fn unused(&self, allowed: &[&str]) -> std::result::Result<(), String> {
        let present = [
            ("size", self.size.is_some()),
            ("radius", self.radius.is_some()),
            ("height", self.height.is_some()),
            ("file", self.file.is_some()),
            ("scale", self.scale.is_some()),
        ];
        match present
            .iter()
            .find(|(name, set)| *set && !allowed.contains(name))
        {
            Some((name, _)) => Err(format!("a {} has no `{name}`", self.shape)),
            None => Ok(()),
        }
    }

    /// The shape in its own frame, its kind, triangle count and the local
    /// pose of parry's shape in the object frame. Errors name `scene` (or the
    /// mesh file) and start with `label`.
    fn build(
        &self,
        scene: &Path,
        label: &str,
    ) -> Result<(SharedShape, &'static str, usize, ParryPose)> {
        let bad = |msg: String| Error::input(scene, format!("{label}{msg}"));
        let local = ParryPose::identity();
        match self.shape.as_str() {
            "box" => {
                self.unused(&["size"]).map_err(bad)?;
                let size = self.size.ok_or_else(|| {
                    bad("a box needs `size = [x, y, z]` (full edge lengths, m)".into())
                })?;
                if size.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
                    return Err(bad(format!(
                        "box size {size:?} must be positive lengths (m)"
                    )));
                }
                if size.iter().any(|s| *s > 2.0 * MAX_MESH_REACH) {
                    return Err(bad(past_any_workcell(format!("box size {size:?}"))));
                }
                Ok((
                    SharedShape::cuboid(size[0] / 2.0, size[1] / 2.0, size[2] / 2.0),
                    "box",
                    0,
                    local,
                ))
            }
            "sphere" => {
                self.unused(&["radius"]).map_err(bad)?;
                let r = positive(self.radius, "radius", "sphere", MAX_MESH_REACH).map_err(bad)?;
                Ok((SharedShape::ball(r), "sphere", 0, local))
            }
            "cylinder" => {
                self.unused(&["radius", "height"]).map_err(bad)?;
                let r = positive(self.radius, "radius", "cylinder", MAX_MESH_REACH).map_err(bad)?;
                let h = positive(self.height, "height", "cylinder", 2.0 * MAX_MESH_REACH)
                    .map_err(bad)?;
                // parry's cylinder runs along its y axis; ours along z.
                let y_to_z = ParryPose::from_rotation(ParryRotation::from_rotation_x(
                    std::f64::consts::FRAC_PI_2,
                ));
                Ok((SharedShape::cylinder(h / 2.0, r), "cylinder", 0, y_to_z))
            }
            "mesh" => {
                self.unused(&["file", "scale"]).map_err(bad)?;
                let file = self.file.as_ref().ok_or_else(|| {
                    bad(
                        "a mesh needs `file` (an .obj, .stl or .ply path relative to the scene file)"
                            .into(),
                    )
                })?;
                let scale = match self.scale {
                    None => Vector3::repeat(1.0),
                    Some(Scale::Uniform(s)) => Vector3::repeat(s),
                    Some(Scale::PerAxis(s)) => Vector3::from(s),
                };
                if scale.iter().any(|s| !s.is_finite() || *s == 0.0) {
                    return Err(bad(format!(
                        "mesh scale {:?} must be finite and non-zero",
                        scale.as_slice()
                    )));
                }
                let path = scene.parent().unwrap_or(Path::new(".")).join(file);
                let in_scene = |e: Error| e.context(format!("{label}(from {}) ", scene.display()));
                let mesh = Mesh::load(&path).map_err(in_scene)?.scaled(scale);
                // A workcell lies within the octree's reach at its coarsest
                // resolution; beyond, the geometry is not a workcell's.
                let far = mesh
                    .vertices
                    .iter()
                    .map(|v| v.iter().fold(0.0f64, |m, c| m.max(c.abs())))
                    .fold(0.0f64, f64::max);
                if far.is_nan() || far > MAX_MESH_REACH {
                    return Err(bad(format!(
                        "mesh scale {:?} puts vertices {far:.3e} m from the object's origin: \
                         a workcell's mesh lies within {} km",
                        scale.as_slice(),
                        MAX_MESH_REACH / 1000.0
                    )));
                }
                let input = |what: String| in_scene(Error::input(&path, what));
                mesh.check_closed().map_err(input)?;
                let n = mesh.triangles.len();
                let vertices = mesh.vertices.iter().map(to_parry).collect();
                let mut trimesh = TriMesh::new(vertices, mesh.triangles)
                    .map_err(|e| input(format!("cannot build the mesh: {e:?}")))?;
                trimesh
                    .set_flags(TriMeshFlags::ORIENTED | TriMeshFlags::HALF_EDGE_TOPOLOGY)
                    .map_err(|e| input(format!("bad mesh topology: {e:?}")))?;
                Ok((SharedShape::new(trimesh), "mesh", n, local))
            }
            other => Err(bad(format!(
                "unknown shape '{other}' (use box, cylinder, sphere or mesh)"
            ))),
        }
    }
}

/// Most cells on the boundary of a region the ground truth is computed
/// over: the truth is split to single cells there, about 12 bytes each in
/// the tree (1e8: about 1.2 GB).
pub const MAX_TRUTH_BOUNDARY_CELLS: f64 = 1e8;

/// The farthest a scaled mesh's vertex, or a box's, sphere's or cylinder's
/// surface, may lie from its object's origin (m): 10 km, past any workcell
/// and within the octree's reach.
const MAX_MESH_REACH: f64 = 1e4;

impl Scene {
    /// Checks that the workspace fits an octree at `resolution` (±32 768
    /// cells around the origin on each axis), before anything is allocated;
    /// the error names the scene file. Its volume is not bounded: the
    /// ground truth, the observable mask and the scores grow with the
    /// surfaces and the observed volume.
    pub fn check_resolution(&self, resolution: f64) -> Result<()> {
        crate::mapping::octree::check_span(self.workspace.reach(), resolution)
            .map_err(|e| Error::input(&self.source, e))
    }

    /// Checks that the ground truth over `region` (scene frame; cut to the
    /// workspace) stays within [`MAX_TRUTH_BOUNDARY_CELLS`] cells on its
    /// boundary at `resolution`, before anything is allocated: the truth is
    /// split to single cells there (its surfaces' cells come on top, and
    /// they lie inside the region). `what` says what the region is.
    pub fn check_truth_region(&self, region: &Bounds, resolution: f64, what: &str) -> Result<()> {
        let ws = &self.workspace;
        let n: Vec<f64> = (0..3)
            .map(|k| {
                ((region.max[k].min(ws.max[k]) - region.min[k].max(ws.min[k])) / resolution)
                    .ceil()
                    .max(0.0)
            })
            .collect();
        let cells = 2.0 * (n[0] * n[1] + n[0] * n[2] + n[1] * n[2]);
        if cells <= MAX_TRUTH_BOUNDARY_CELLS {
            return Ok(());
        }
        Err(Error::input(
            &self.source,
            format!(
                "the ground truth over {what} at {resolution} m has {cells:.2e} cells on its \
                 boundary alone; sigmap handles at most {MAX_TRUTH_BOUNDARY_CELLS:.0e} (use a \
                 coarser resolution, a smaller workspace or a shorter max_range)"
            ),
        ))
    }

    /// Reads a scene file. Mesh paths are relative to the scene file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with(path, &[])
    }

    /// Reads a scene with numeric fields overridden (dotted paths, e.g.
    /// `object.2.radius`).
    pub fn load_with(path: &Path, overrides: &[(String, toml::Value)]) -> Result<Self> {
        let file: SceneFile = read_toml_with(path, overrides)?;
        let bad = |msg: String| Error::input(path, msg);
        let ws = &file.workspace;
        if ws.min.iter().chain(&ws.max).any(|v| !v.is_finite())
            || (0..3).any(|k| ws.min[k] >= ws.max[k])
        {
            return Err(bad(format!(
                "[workspace] min {:?} must be below max {:?} on every axis",
                ws.min, ws.max
            )));
        }
        let workspace = Bounds {
            min: Point3::from(ws.min),
            max: Point3::from(ws.max),
        };
        if file.objects.is_empty() {
            return Err(bad("the scene has no [[object]]".into()));
        }
        let mut objects = Vec::with_capacity(file.objects.len());
        let mut inputs = vec![path.to_path_buf()];
        let mut notes = Vec::new();
        for (index, spec) in file.objects.iter().enumerate() {
            if let (Some(mesh), "mesh") = (&spec.file, spec.shape.as_str()) {
                inputs.push(path.parent().unwrap_or(Path::new(".")).join(mesh));
            }
            let name = spec
                .name
                .clone()
                .unwrap_or_else(|| format!("{} #{index}", spec.shape));
            let label = format!("object '{name}': ");
            let placement = Pose::new(spec.xyz, spec.rpy);
            if !placement.is_finite() {
                return Err(bad(format!("{label}xyz/rpy must be finite")));
            }
            notes
                .extend(placement.degrees_note(&format!("object '{name}' of {}:", path.display())));
            let (shape, kind, triangles, local) = spec.build(path, &label)?;
            let pose = to_parry_pose(&placement.to_isometry()) * local;
            let aabb = shape.compute_aabb(&pose);
            let bounds = Bounds {
                min: Point3::new(aabb.mins.x, aabb.mins.y, aabb.mins.z),
                max: Point3::new(aabb.maxs.x, aabb.maxs.y, aabb.maxs.z),
            };
            if !bounds.intersects(&workspace) {
                return Err(bad(format!("{label}lies entirely outside the workspace")));
            }
            let cylinder = shape.as_cylinder().map(|c| (c.radius, c.half_height));
            objects.push(SceneObject {
                name,
                kind,
                triangles,
                bounds,
                pose,
                shape,
                cylinder,
            });
        }
        let leaves: Vec<Aabb> = objects
            .iter()
            .map(|o| o.shape.compute_aabb(&o.pose))
            .collect();
        let bvh = Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves);
        let mut scene = Self {
            name: file.name.unwrap_or_else(|| crate::files::stem(path)),
            source: path.to_path_buf(),
            description: file.description,
            workspace,
            inputs,
            notes,
            objects,
            bvh,
        };
        let oversized: Vec<String> = (0..scene.objects.len())
            .filter_map(|index| {
                let span = scene.oversized_mesh(index)?;
                Some(format!(
                    "note: object '{}' of {} spans {span:.3} m, {:.0} times the workspace's \
                     diagonal: {MILLIMETRES}",
                    scene.objects[index].name,
                    path.display(),
                    span / scene.workspace.diagonal()
                ))
            })
            .collect();
        scene.notes.extend(oversized);
        Ok(scene)
    }

    /// What the user should know of the scene file that is not an error: an
    /// object turned by more than a full turn (degrees for radians), a mesh
    /// far larger than the workspace (millimetres for metres).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The solids.
    pub fn objects(&self) -> &[SceneObject] {
        &self.objects
    }

    /// The diagonal (m) of object `index`'s bounding box if it is a mesh
    /// more than [`MESH_SPAN_RATIO`] times the workspace's diagonal across:
    /// a mesh written in millimetres and read as metres, most likely.
    pub fn oversized_mesh(&self, index: usize) -> Option<f64> {
        let object = self.objects.get(index)?;
        let span = object.bounds.diagonal();
        (object.kind == "mesh" && span > MESH_SPAN_RATIO * self.workspace.diagonal())
            .then_some(span)
    }

    /// Total triangle count of the meshes.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.triangles).sum()
    }

    /// Distance along the unit direction `dir` from `origin` to the first
    /// surface within `max_range`, and the object hit.
    #[inline]
    pub fn cast_ray(&self, origin: &Point3, dir: &Vector3, max_range: f64) -> Option<(f64, usize)> {
        let ray = Ray::new(to_parry(&origin.coords), to_parry(dir));
        self.bvh
            .cast_ray(&ray, max_range, |i, best| {
                let object = &self.objects[i as usize];
                match object.cylinder {
                    Some((radius, half_height)) => {
                        let local = ray.inverse_transform_by(&object.pose);
                        cast_cylinder(radius, half_height, local.origin, local.dir, best)
                    }
                    None => object.shape.cast_ray(&object.pose, &ray, best, true),
                }
            })
            .map(|(i, toi)| (toi, i as usize))
    }

    /// The first object whose solid contains `p`, if any.
    pub fn object_containing(&self, p: &Point3) -> Option<usize> {
        let q = to_parry(&p.coords);
        let probe = Aabb::new(q, q);
        let found = self.bvh.intersect_aabb(&probe).find(|&i| {
            let object = &self.objects[i as usize];
            object.shape.contains_point(&object.pose, q)
        });
        found.map(|i| i as usize)
    }
}

impl Scene {
    /// Indices of the objects whose bounding boxes meet the box `[min, max]`.
    pub fn objects_near(&self, min: &Point3, max: &Point3) -> Vec<usize> {
        let aabb = Aabb::new(to_parry(&min.coords), to_parry(&max.coords));
        let found: Vec<usize> = self.bvh.intersect_aabb(&aabb).map(|i| i as usize).collect();
        found
    }

    /// Whether the closed box of half-extents `half`, centred on the origin
    /// of the frame `scene_from_box` (any orientation), meets object
    /// `object`'s solid (its surface or its interior): the ground-truth
    /// occupancy rule.
    pub fn box_meets_object(
        &self,
        object: usize,
        scene_from_box: &Isometry3,
        half: &Vector3,
    ) -> bool {
        let o = &self.objects[object];
        let centre = scene_from_box.translation.vector;
        if o.shape.contains_point(&o.pose, to_parry(&centre)) {
            return true;
        }
        let cell = parry3d_f64::shape::Cuboid::new(to_parry(half));
        parry3d_f64::query::intersection_test(
            &to_parry_pose(scene_from_box),
            &cell,
            &o.pose,
            o.shape.as_ref(),
        )
        .map_or(true, |r| r.intersecting)
    }

    /// Whether the closed box of half-extents `half` in the frame
    /// `scene_from_box` lies wholly inside object `object`'s solid: all
    /// eight corners inside a convex solid (box, cylinder, sphere). Always
    /// false for a mesh, which may be concave. Lets the ground truth call a
    /// whole block occupied without visiting its cells.
    pub fn box_inside_object(
        &self,
        object: usize,
        scene_from_box: &Isometry3,
        half: &Vector3,
    ) -> bool {
        let o = &self.objects[object];
        if o.kind == "mesh" {
            return false;
        }
        (0..8u8).all(|corner| {
            let local = Vector3::from_fn(|k, _| {
                if corner >> k & 1 == 1 {
                    half[k]
                } else {
                    -half[k]
                }
            });
            let p = scene_from_box * Point3::from(local);
            o.shape.contains_point(&o.pose, to_parry(&p.coords))
        })
    }
}

mod cylinder;
#[cfg(test)]
mod tests;
