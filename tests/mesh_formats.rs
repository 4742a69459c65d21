//! Scene meshes in every format sigmap reads give the same solid: the
//! tabletop's bunny as a PLY written by an independent writer (Python's
//! `plyfile`) has the same ground truth, cell for cell, as its OBJ.

mod common;

use common::{root, sigmap_ok, tool_ok};
use std::process::Command;

/// Writes `obj`'s vertices and triangles as a binary PLY with `plyfile`
/// (doubles, `int` indices: the OBJ's numbers exactly).
fn obj_to_ply(obj: &std::path::Path, ply: &std::path::Path) {
    let script = "import sys, numpy as np\n\
                  from plyfile import PlyData, PlyElement\n\
                  vs, fs = [], []\n\
                  for line in open(sys.argv[1]):\n\
                  \x20   w = line.split()\n\
                  \x20   if w and w[0] == 'v': vs.append(tuple(float(x) for x in w[1:4]))\n\
                  \x20   if w and w[0] == 'f': fs.append(([int(x.split('/')[0]) - 1 for x in w[1:]],))\n\
                  v = np.array(vs, dtype=[('x', 'f8'), ('y', 'f8'), ('z', 'f8')])\n\
                  f = np.array(fs, dtype=[('vertex_indices', 'i4', (3,))])\n\
                  PlyData([PlyElement.describe(v, 'vertex'), PlyElement.describe(f, 'face')]).write(sys.argv[2])\n";
    tool_ok(Command::new("python3").args([
        "-c",
        script,
        obj.to_str().unwrap(),
        ply.to_str().unwrap(),
    ]));
}

#[test]
#[ignore = "needs python3 with plyfile (pip install plyfile); .ci/run runs it"]
fn a_ply_from_an_independent_writer_is_the_same_solid_as_its_obj() {
    common::require_plyfile();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("meshes")).unwrap();
    obj_to_ply(
        &root().join("scenes/meshes/bunny.obj"),
        &d.join("meshes/bunny.ply"),
    );
    std::fs::copy(
        root().join("scenes/meshes/bunny.obj"),
        d.join("meshes/bunny.obj"),
    )
    .unwrap();
    let scene = std::fs::read_to_string(root().join("scenes/tabletop.toml")).unwrap();
    assert!(scene.contains("meshes/bunny.obj"));
    std::fs::write(d.join("obj.toml"), &scene).unwrap();
    std::fs::write(
        d.join("ply.toml"),
        scene.replace("meshes/bunny.obj", "meshes/bunny.ply"),
    )
    .unwrap();
    let truth = |name: &str| {
        let out = d.join(format!("{name}.bt"));
        sigmap_ok(&[
            "ground-truth",
            d.join(format!("{name}.toml")).to_str().unwrap(),
            "--resolution",
            "0.005",
            "--out",
            out.to_str().unwrap(),
        ]);
        std::fs::read(out).unwrap()
    };
    let (obj, ply) = (truth("obj"), truth("ply"));
    assert!(obj.len() > 1000);
    assert!(obj == ply, "the PLY's ground truth differs from the OBJ's");
}
