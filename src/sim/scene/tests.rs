use super::*;

fn write_scene(dir: &Path, body: &str) -> PathBuf {
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        format!("[workspace]\nmin = [-2, -2, -2]\nmax = [2, 2, 2]\n{body}"),
    )
    .unwrap();
    path
}

fn load_err(body: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(dir.path(), body);
    let err = Scene::load(&path).err().expect("scene should be rejected");
    assert_eq!(err.exit_code(), 2);
    err.to_string()
}

#[test]
fn ray_hits_sphere_at_the_analytic_distance() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(
        dir.path(),
        "[[object]]\nshape = \"sphere\"\nradius = 0.25\nxyz = [1.0, 0.5, 0.0]\n",
    );
    let scene = Scene::load(&path).unwrap();
    let origin = Point3::new(-1.0, 0.5, 0.0);
    let (toi, obj) = scene.cast_ray(&origin, &Vector3::x(), 10.0).unwrap();
    assert_eq!(obj, 0);
    assert!((toi - 1.75).abs() < 1e-12, "{toi}");
    // An oblique ray: distance to a sphere from the quadratic formula.
    let dir_v = Vector3::new(1.0, 0.1, 0.05).normalize();
    let oc = origin - Point3::new(1.0, 0.5, 0.0);
    let b = oc.dot(&dir_v);
    let expected = -b - (b * b - (oc.norm_squared() - 0.0625)).sqrt();
    let (toi, _) = scene.cast_ray(&origin, &dir_v, 10.0).unwrap();
    assert!((toi - expected).abs() < 1e-12);
    // Misses and range limits are no hit.
    assert!(scene.cast_ray(&origin, &Vector3::y(), 10.0).is_none());
    assert!(scene.cast_ray(&origin, &Vector3::x(), 1.7).is_none());
}

#[test]
fn cylinder_axis_is_z_and_boxes_use_full_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(
        dir.path(),
        "[[object]]\nshape = \"cylinder\"\nradius = 0.1\nheight = 1.0\n\
         [[object]]\nname = \"slab\"\nshape = \"box\"\nsize = [0.2, 0.4, 0.6]\nxyz = [1, 0, 0]\nrpy = [0, 0, 1.5707963267948966]\n",
    );
    let scene = Scene::load(&path).unwrap();
    // Down the cylinder's axis from above: hits its top cap at z = 0.5.
    let (toi, _) = scene
        .cast_ray(&Point3::new(0.0, 0.0, 1.5), &-Vector3::z(), 5.0)
        .unwrap();
    assert!((toi - 1.0).abs() < 1e-9);
    // From the side: its radius.
    let (toi, _) = scene
        .cast_ray(&Point3::new(0.0, -1.0, 0.3), &Vector3::y(), 5.0)
        .unwrap();
    assert!((toi - 0.9).abs() < 1e-9);
    // The box turned by 90° about z: its 0.4 m side now lies along x.
    let (toi, obj) = scene
        .cast_ray(&Point3::new(0.5, 0.05, -0.1), &Vector3::x(), 5.0)
        .unwrap();
    assert_eq!(scene.objects()[obj].name, "slab");
    assert!((toi - 0.3).abs() < 1e-9, "{toi}");
    assert_eq!(
        scene.object_containing(&Point3::new(1.15, 0.0, 0.25)),
        Some(obj)
    );
    assert_eq!(scene.object_containing(&Point3::new(1.25, 0.0, 0.0)), None);
}

#[test]
fn shipped_scenes_load_and_bunny_contains_its_centre() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for name in ["tabletop", "shelf", "slanted"] {
        let scene = Scene::load(&root.join(format!("{name}.toml"))).unwrap();
        assert!(!scene.objects().is_empty(), "{name}");
    }
    let tabletop = Scene::load(&root.join("tabletop.toml")).unwrap();
    assert!(tabletop.triangle_count() > 3000);
    let bunny = tabletop
        .objects()
        .iter()
        .position(|o| o.kind == "mesh")
        .unwrap();
    let b = tabletop.objects()[bunny].bounds;
    let centre = Point3::from((b.min.coords + b.max.coords) / 2.0);
    assert_eq!(tabletop.object_containing(&centre), Some(bunny));
}

#[test]
fn bad_scene_inputs_are_named() {
    assert!(load_err("[[object]]\nshape = \"cone\"\nradius = 1\n").contains("unknown shape 'cone'"));
    assert!(load_err("[[object]]\nshape = \"sphere\"\n").contains("needs `radius`"));
    assert!(load_err("[[object]]\nshape = \"sphere\"\nradius = -1\n").contains("positive"));
    assert!(load_err("[[object]]\nshape = \"sphere\"\nradius = nan\n").contains("positive"));
    assert!(
        load_err("[[object]]\nshape = \"sphere\"\nradius = 1\nsize = [1,1,1]\n")
            .contains("has no `size`")
    );
    assert!(load_err("[[object]]\nshape = \"sphere\"\nradus = 1\n").contains("malformed TOML"));
    assert!(
        load_err("[[object]]\nshape = \"sphere\"\nradius = 1\nxyz = [9, 9, 9]\n")
            .contains("outside the workspace")
    );
    assert!(
        load_err("[[object]]\nshape = \"mesh\"\nfile = \"missing.obj\"\n").contains("missing.obj")
    );
    let msg = load_err("[[object]]\nshape = \"box\"\nsize = [1, 1]\n");
    assert!(
        msg.contains("scene.toml") && msg.contains("malformed TOML"),
        "{msg}"
    );

    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("open.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\n",
    )
    .unwrap();
    let path = write_scene(
        dir.path(),
        "[[object]]\nshape = \"mesh\"\nfile = \"open.obj\"\n",
    );
    let msg = Scene::load(&path).err().unwrap().to_string();
    // The object and its scene are named, as for a file that cannot be read.
    assert!(
        msg.contains("open.obj")
            && msg.contains("the mesh is open")
            && msg.contains("object 'mesh #0'")
            && msg.contains("scene.toml"),
        "{msg}"
    );
}

/// A primitive past any workcell is refused as a mesh scaled past one is;
/// a 10 km floor is not.
#[test]
fn a_primitive_past_any_workcell_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (object, refused) in [
        ("shape = \"box\"\nsize = [1e300, 1.0, 0.1]", true),
        ("shape = \"box\"\nsize = [20000.0, 20000.0, 0.1]", false),
        ("shape = \"sphere\"\nradius = 2e4", true),
        ("shape = \"cylinder\"\nradius = 0.1\nheight = 1e300", true),
        ("shape = \"cylinder\"\nradius = 1e4\nheight = 2e4", false),
    ] {
        let path = write_scene(dir.path(), &format!("[[object]]\n{object}\n"));
        match Scene::load(&path) {
            Err(e) => {
                let message = e.to_string();
                assert!(refused, "{object}: {message}");
                assert!(message.contains("past any workcell"), "{object}: {message}");
            }
            Ok(_) => assert!(!refused, "{object} should be refused"),
        }
    }
}

#[test]
fn a_mesh_scaled_past_any_workcell_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/bunny.obj");
    for scale in ["1e200", "[1.0, 1.0, 1e300]"] {
        let path = write_scene(
            dir.path(),
            &format!(
                "[[object]]\nshape = \"mesh\"\nfile = {:?}\nscale = {scale}\n",
                bunny.display().to_string()
            ),
        );
        let err = Scene::load(&path)
            .err()
            .expect("scene should be rejected")
            .to_string();
        assert!(
            err.contains("scale") && err.contains("km"),
            "{scale}: {err}"
        );
    }
}
