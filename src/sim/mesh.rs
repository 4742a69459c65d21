//! Triangle meshes from OBJ, STL and PLY files, checked to be closed and
//! outward.

use crate::error::{Error, Result};
use crate::geometry::Vector3;
use std::collections::HashMap;
use std::path::Path;

/// A triangle soup with shared vertices.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub vertices: Vec<Vector3>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// Most bytes of a mesh file (a few million triangles).
pub const MAX_MESH_BYTES: u64 = 512 << 20;

impl Mesh {
    /// Reads an OBJ (`.obj`), STL (`.stl`, ASCII or binary) or PLY (`.ply`,
    /// ASCII or binary) file.
    pub fn load(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if !path.exists() {
            return Err(Error::input(path, "mesh file not found"));
        }
        crate::error::check_input_file(path, MAX_MESH_BYTES)?;
        let mesh = match ext.as_deref() {
            Some("obj") => Self::load_obj(path)?.welded(),
            Some("stl") => stl::load(path)?,
            Some("ply") => ply::load(path)?.welded(),
            _ => {
                return Err(Error::input(
                    path,
                    "unknown mesh format: use an .obj, .stl or .ply file",
                ))
            }
        };
        if mesh.triangles.is_empty() {
            return Err(Error::input(path, "the mesh has no triangles"));
        }
        if let Some(v) = mesh
            .vertices
            .iter()
            .find(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(Error::input(path, format!("vertex {v:?} is not finite")));
        }
        Ok(mesh)
    }

    fn load_obj(path: &Path) -> Result<Self> {
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: false,
            ..Default::default()
        };
        let (models, _) = tobj::load_obj(path, &options)
            .map_err(|e| Error::input(path, format!("malformed OBJ: {e}")))?;
        let mut mesh = Mesh::default();
        for model in models {
            let base = mesh.vertices.len() as u32;
            mesh.vertices.extend(
                model
                    .mesh
                    .positions
                    .chunks_exact(3)
                    .map(|p| Vector3::new(p[0], p[1], p[2])),
            );
            mesh.triangles.extend(
                model
                    .mesh
                    .indices
                    .chunks_exact(3)
                    .map(|t| [base + t[0], base + t[1], base + t[2]]),
            );
        }
        Ok(mesh)
    }

    /// The mesh with the vertices at exactly the same position merged into
    /// the first of them, as an STL file is read: an exporter that writes a
    /// copy of each vertex for every face it bounds leaves a closed surface
    /// whose triangles share no index. Positions are not rounded, and a
    /// mesh without such copies is returned as it was.
    fn welded(mut self) -> Self {
        let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(self.vertices.len());
        let mut kept = Vec::with_capacity(self.vertices.len());
        let merged: Vec<u32> = self
            .vertices
            .iter()
            .map(|v| {
                // `+ 0.0` makes −0 and +0 one position.
                let at = [v.x, v.y, v.z].map(|c| (c + 0.0).to_bits());
                *first.entry(at).or_insert_with(|| {
                    kept.push(*v);
                    (kept.len() - 1) as u32
                })
            })
            .collect();
        if kept.len() == self.vertices.len() {
            return self;
        }
        for i in self.triangles.iter_mut().flatten() {
            // An index past the end stays past it, for `check_closed` to name.
            *i = merged.get(*i as usize).copied().unwrap_or(u32::MAX);
        }
        self.vertices = kept;
        self
    }

    /// Multiplies every vertex by `scale` (per axis). A negative determinant
    /// mirrors the mesh, so the triangles are flipped to stay outward.
    pub fn scaled(mut self, scale: Vector3) -> Self {
        for v in &mut self.vertices {
            *v = v.component_mul(&scale);
        }
        if scale.x * scale.y * scale.z < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
        }
        self
    }

    /// Signed volume (positive for a closed mesh with outward faces).
    pub fn signed_volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Checks that the mesh bounds a solid: no degenerate triangle, every edge
    /// shared by exactly two triangles that use it in opposite directions
    /// (closed and consistently oriented), and outward faces (positive volume).
    pub fn check_closed(&self) -> std::result::Result<(), String> {
        let n = self.vertices.len() as u32;
        let mut directed: HashMap<(u32, u32), u32> =
            HashMap::with_capacity(self.triangles.len() * 3);
        for (k, t) in self.triangles.iter().enumerate() {
            if t.iter().any(|&i| i >= n) {
                return Err(format!(
                    "triangle {k} refers to a vertex that does not exist"
                ));
            }
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return Err(format!("triangle {k} is degenerate (repeats a vertex)"));
            }
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                *directed.entry((a, b)).or_default() += 1;
            }
        }
        let repeated = directed.values().filter(|&&c| c > 1).count();
        if repeated > 0 {
            return Err(format!(
                "{repeated} edges are used twice in the same direction: triangles are \
                 inconsistently oriented or the mesh is not manifold"
            ));
        }
        let open = directed
            .keys()
            .filter(|(a, b)| !directed.contains_key(&(*b, *a)))
            .count();
        if open > 0 {
            return Err(format!(
                "the mesh is open: {open} boundary edges (close its holes so it bounds a solid)"
            ));
        }
        let volume = self.signed_volume();
        if volume <= 0.0 {
            return Err(format!(
                "the mesh is inverted: its faces point inward (signed volume {volume:.3e}); \
                 flip the triangle winding"
            ));
        }
        Ok(())
    }
}

mod ply;
mod stl;

#[cfg(test)]
mod tests {
    use super::*;

    fn cube_obj() -> String {
        let mut s = String::new();
        for z in [0.0, 1.0] {
            for y in [0.0, 1.0] {
                for x in [0.0, 1.0] {
                    s += &format!("v {x} {y} {z}\n");
                }
            }
        }
        // Outward quads (1-based), triangulated by the reader.
        s += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
        s
    }

    #[test]
    fn closed_cube_passes_and_open_or_inverted_fail() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cube.obj");
        std::fs::write(&path, cube_obj()).unwrap();
        let mesh = Mesh::load(&path).unwrap();
        assert_eq!(mesh.triangles.len(), 12);
        mesh.check_closed().unwrap();
        assert!((mesh.signed_volume() - 1.0).abs() < 1e-12);

        let mut open = mesh.clone();
        open.triangles.pop();
        assert!(open.check_closed().unwrap_err().contains("open"));

        let mut inverted = mesh.clone();
        for t in &mut inverted.triangles {
            t.swap(1, 2);
        }
        assert!(inverted.check_closed().unwrap_err().contains("inverted"));

        let mirrored = mesh.scaled(Vector3::new(-1.0, 1.0, 1.0));
        mirrored.check_closed().unwrap();
    }

    #[test]
    fn an_obj_with_a_copy_of_each_vertex_per_face_is_one_closed_surface() {
        let dir = tempfile::tempdir().unwrap();
        let cube = Mesh::load(&{
            let path = dir.path().join("cube.obj");
            std::fs::write(&path, cube_obj()).unwrap();
            path
        })
        .unwrap();
        // Every triangle with vertices of its own, as some exporters write.
        let mut text = String::new();
        for (k, t) in cube.triangles.iter().enumerate() {
            for &i in t {
                let v = cube.vertices[i as usize];
                text += &format!("v {} {} {}\n", v.x, v.y, v.z);
            }
            text += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
        }
        let path = dir.path().join("split.obj");
        std::fs::write(&path, text).unwrap();
        let split = Mesh::load(&path).unwrap();
        assert_eq!(split.vertices.len(), 8);
        assert_eq!(split.triangles.len(), 12);
        split.check_closed().unwrap();
        assert!((split.signed_volume() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bunny_is_closed() {
        let path =
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/bunny.obj");
        let mesh = Mesh::load(&path).unwrap();
        assert!(mesh.triangles.len() > 3000);
        mesh.check_closed().unwrap();
    }

    #[test]
    fn stl_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let obj = dir.path().join("cube.obj");
        std::fs::write(&obj, cube_obj()).unwrap();
        let mesh = Mesh::load(&obj).unwrap();
        let triangles: Vec<stl_io::Triangle> = mesh
            .triangles
            .iter()
            .map(|t| {
                let v = t.map(|i| {
                    let p = mesh.vertices[i as usize];
                    stl_io::Vertex::new([p.x as f32, p.y as f32, p.z as f32])
                });
                stl_io::Triangle {
                    normal: stl_io::Normal::new([0.0; 3]),
                    vertices: v,
                }
            })
            .collect();
        let stl = dir.path().join("cube.stl");
        let mut file = std::fs::File::create(&stl).unwrap();
        stl_io::write_stl(&mut file, triangles.iter()).unwrap();
        drop(file);
        let back = Mesh::load(&stl).unwrap();
        back.check_closed().unwrap();
        assert!((back.signed_volume() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn missing_and_malformed_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let msg = Mesh::load(&dir.path().join("nope.obj"))
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("nope.obj") && msg.contains("not found"),
            "{msg}"
        );
        let bad = dir.path().join("bad.obj");
        std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
        assert!(Mesh::load(&bad).is_err());
        let collada = dir.path().join("x.dae");
        std::fs::write(&collada, "<COLLADA/>").unwrap();
        assert!(Mesh::load(&collada)
            .unwrap_err()
            .to_string()
            .contains(".obj, .stl or .ply"));
    }
}
