use super::*;

/// The unit cube's corners, `x` fastest, and its six faces as outward quads.
const CORNERS: [[f64; 3]; 8] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [0.0, 1.0, 1.0],
    [1.0, 1.0, 1.0],
];
const QUADS: [[u32; 4]; 6] = [
    [0, 2, 3, 1],
    [4, 5, 7, 6],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 4, 6, 2],
    [1, 3, 7, 5],
];

/// An ASCII PLY of the cube with normals-like extras, an `edge` element
/// and CRLF line ends, as MeshLab-style writers may add.
fn ascii_cube() -> String {
    let mut s = String::from(
        "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nelement vertex 8\r\n\
         property float x\r\nproperty float y\r\nproperty float z\r\n\
         property uchar red\r\nelement face 6\r\nproperty list uchar int vertex_indices\r\n\
         element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\nend_header\r\n",
    );
    for c in CORNERS {
        s += &format!("{} {} {} 200\r\n", c[0], c[1], c[2]);
    }
    for q in QUADS {
        s += &format!("4 {} {} {} {}\r\n", q[0], q[1], q[2], q[3]);
    }
    s + "0 1\r\n"
}

/// A binary PLY of the cube in triangles: doubles, `uint` indices under
/// the name `vertex_index`, little- or big-endian.
fn binary_cube(big_endian: bool) -> Vec<u8> {
    let order = if big_endian { "big" } else { "little" };
    let mut out = format!(
        "ply\nformat binary_{order}_endian 1.0\nelement vertex 8\nproperty double x\n\
         property double y\nproperty double z\nelement face 12\n\
         property list uchar uint vertex_index\nend_header\n"
    )
    .into_bytes();
    let f64_bytes = |x: f64| {
        if big_endian {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    let u32_bytes = |x: u32| {
        if big_endian {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    for c in CORNERS {
        for x in c {
            out.extend(f64_bytes(x));
        }
    }
    for q in QUADS {
        for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            out.push(3);
            for i in t {
                out.extend(u32_bytes(i));
            }
        }
    }
    out
}

fn write(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Each encoding reads as the same closed, outward unit cube.
#[test]
fn ascii_and_binary_cubes_are_the_same_closed_solid() {
    let dir = tempfile::tempdir().unwrap();
    let files = [
        write(&dir, "ascii.ply", ascii_cube().as_bytes()),
        write(&dir, "le.ply", &binary_cube(false)),
        write(&dir, "be.ply", &binary_cube(true)),
    ];
    for path in files {
        let mesh = Mesh::load(&path).unwrap();
        assert_eq!(mesh.vertices.len(), 8, "{path:?}");
        assert_eq!(mesh.triangles.len(), 12, "{path:?}");
        mesh.check_closed().unwrap();
        assert!((mesh.signed_volume() - 1.0).abs() < 1e-12, "{path:?}");
        for (v, c) in mesh.vertices.iter().zip(CORNERS) {
            assert_eq!(*v, Vector3::from(c));
        }
    }
}

/// Every problem is an error naming the file, before the body is read
/// where the header already tells.
#[test]
fn bad_files_are_named_with_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let cube = ascii_cube();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "cloud.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nend_header\n0 0 0\n"
                .to_vec(),
            "point cloud",
        ),
        (
            "count.ply",
            cube.replace("element face 6", "element face 6000000")
                .into_bytes(),
            "cut short or a count is wrong",
        ),
        (
            "huge.ply",
            cube.replace("element vertex 8", "element vertex 4000000000")
                .into_bytes(),
            "at most 10000000",
        ),
        (
            "digits.ply",
            cube.replace("element face 6", "element face 99999999999999999999999")
                .into_bytes(),
            "holds the number 999999999999…",
        ),
        (
            "index.ply",
            cube.replace("4 1 3 7 5", "4 1 3 7 9").into_bytes(),
            "uses vertex 9, but the file has 8 vertices",
        ),
        (
            "negative.ply",
            cube.replace("4 1 3 7 5", "4 1 3 7 -5").into_bytes(),
            "face 5 has a negative",
        ),
        (
            "line.ply",
            cube.replace("4 1 3 7 5", "2 1 3").into_bytes(),
            "face 5 has 2 corners",
        ),
        (
            "noz.ply",
            cube.replace("property float z", "property float w")
                .into_bytes(),
            "no `z` property",
        ),
        (
            "text.ply",
            b"solid cube\nendsolid\n".to_vec(),
            "malformed PLY (header): Line 1: Expected magic number 'ply'.",
        ),
        (
            "ascii.ply",
            cube.replace("4 1 3 7 5", "4 1 3 x 5").into_bytes(),
            "malformed PLY: `face` element 5: Couldn't read element line.",
        ),
        (
            "short.ply",
            binary_cube(false)[..300].to_vec(),
            "cut short or a count is wrong",
        ),
        (
            "end.ply",
            {
                let cube = binary_cube(false);
                cube[..cube.len() - 5].to_vec()
            },
            "ends within its `face` elements",
        ),
    ];
    for (name, bytes, expected) in cases {
        let path = write(&dir, name, &bytes);
        let message = Mesh::load(&path).unwrap_err().to_string();
        assert!(
            message.contains(name) && message.contains(expected) && !message.contains('\n'),
            "{name}: {message}"
        );
    }
}

/// A mesh written with a copy of each corner per face (as some exporters
/// write PLY) is welded into one closed surface.
#[test]
fn a_ply_with_a_copy_of_each_corner_per_face_is_welded() {
    let mut s = String::from(
        "ply\nformat ascii 1.0\nelement vertex 24\nproperty double x\nproperty double y\n\
         property double z\nelement face 6\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for q in QUADS {
        for i in q {
            let c = CORNERS[i as usize];
            s += &format!("{} {} {}\n", c[0], c[1], c[2]);
        }
    }
    for k in 0..6 {
        s += &format!("4 {} {} {} {}\n", 4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3);
    }
    let dir = tempfile::tempdir().unwrap();
    let mesh = Mesh::load(&write(&dir, "split.ply", s.as_bytes())).unwrap();
    assert_eq!(mesh.vertices.len(), 8);
    mesh.check_closed().unwrap();
}

/// Polygons are counted as the triangles they make: a file within the
/// limit of faces whose fans pass the limit of triangles is refused.
#[test]
fn the_triangles_of_large_polygons_are_counted_against_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, "quads.ply", ascii_cube().as_bytes());
    assert_eq!(load_at_most(&path, 12).unwrap().triangles.len(), 12);
    let message = load_at_most(&path, 11).unwrap_err().to_string();
    assert!(message.contains("more than 11 triangles"), "{message}");
    let message = load_at_most(&path, 7).unwrap_err().to_string();
    assert!(message.contains("counts 8 elements `vertex`"), "{message}");
}
