//! `sigmap export`: the scans of one run for another mapper — an OctoMap
//! ScanGraph, one PLY per viewpoint, the poses as a TUM trajectory, a depth
//! camera's images in the TUM RGB-D layout, and a README saying what the
//! frames are. Only what a real robot would record: the measurements and
//! the nominal (believed) poses, never the truth.

use crate::error::{Error, Result};
use crate::experiment::write_ply;
use crate::files::write_folder;
use crate::geometry::{Isometry3, Point3, Vector3};
use crate::mapping::depth_images::{depth_png, DepthCamera};
use crate::mapping::measured::ray_inputs;
use crate::mapping::scan::{BeamStatus, MapperView, Scan};
use crate::mapping::scan_graph::{to_scan_graph, ScanNode};
use std::fmt::Write as _;
use std::path::Path;

/// A no-return beam is written as a point this many maximum ranges away, so
/// that `graph2tree -m MAX_RANGE` truncates it and clears free space up to
/// the maximum range, as sigmap's ray update does.
pub const NO_RETURN_REACH: f64 = 2.0;

/// The graph nodes of `scans`: per scan its nominal pose in the map frame
/// (`map = scene + offset`, the run's grid offset) and its end points in
/// the sensor frame (hits at their measured range, no-return beams at
/// [`NO_RETURN_REACH`] maximum ranges; too-close and dropped beams left out).
pub fn scan_nodes(view: &MapperView, scans: &[Scan], offset: &Vector3) -> Vec<ScanNode> {
    let far = NO_RETURN_REACH * view.max_range;
    let map_from_scene = Isometry3::translation(offset.x, offset.y, offset.z);
    scans
        .iter()
        .enumerate()
        .map(|(i, scan)| ScanNode {
            pixels: None,
            id: scan.viewpoint as u32,
            map_from_sensor: map_from_scene * scan.chain.scene_from_camera(),
            points: scan
                .measurements
                .iter()
                .zip(&view.layouts.of(i).directions)
                .filter_map(|(m, d)| match m.status {
                    BeamStatus::Hit => Some(Point3::from(d * m.range)),
                    BeamStatus::NoReturn => Some(Point3::from(d * far)),
                    _ => None,
                })
                .collect(),
        })
        .collect()
}

/// The `graph2tree` command that builds OctoMap's map of an export.
pub fn graph2tree_command(dir: &Path, resolution: f64, max_range: f64) -> String {
    format!(
        "graph2tree -i {} -o map.bt -res {resolution} -m {max_range}",
        dir.join("scans.graph").display()
    )
}

/// The map a run's export is for: its resolution and where its frame sits
/// (`map = scene + offset`, `Experiment::map_offset`).
#[derive(Clone, Copy, Debug)]
pub struct MapFrame<'a> {
    /// The map's resolution (m), for the README's graph2tree command.
    pub resolution: f64,
    /// `map = scene + offset`.
    pub offset: &'a Vector3,
    /// A pinhole sensor's intrinsics (`Scanner::camera`): its scans are also
    /// written as depth images.
    pub camera: Option<&'a DepthCamera>,
}

/// Writes the export of `scans` into the folder `out` (staged, then
/// renamed): `scans.graph`, `vp_NNN.ply`, `poses.txt`, `README.txt`, in
/// the map frame `map = scene + offset` (`Experiment::map_offset`), so that
/// `sigmap score` scores a map of them as `sigmap run` scores its own.
/// `what` names the experiment, seed and cell for the README.
pub fn write_export(
    out: &Path,
    view: &MapperView,
    scans: &[Scan],
    frame: &MapFrame,
    what: &str,
) -> Result<()> {
    let MapFrame {
        resolution,
        offset,
        camera,
    } = *frame;
    let nodes = scan_nodes(view, scans, offset);
    write_folder(out, |dir| {
        if let Some(camera) = camera {
            write_depth_images(dir, view, scans, camera)?;
        }
        let graph = dir.join("scans.graph");
        std::fs::write(&graph, to_scan_graph(&nodes)).map_err(|e| Error::io(&graph, e))?;
        let mut poses = format!("# timestamp tx ty tz qx qy qz qw (TUM): map_from_sensor per viewpoint (map = scene + {:?} m); timestamp = viewpoint index\n", [offset.x, offset.y, offset.z]);
        for (i, (node, scan)) in nodes.iter().zip(scans).enumerate() {
            let t = node.map_from_sensor.translation.vector;
            let q = node.map_from_sensor.rotation;
            let _ = writeln!(
                poses,
                "{} {:?} {:?} {:?} {:?} {:?} {:?} {:?}",
                node.id, t.x, t.y, t.z, q.i, q.j, q.k, q.w
            );
            // The measured hits, as the ray update takes them, in the map frame.
            let (_, hits, _) = ray_inputs(view.layouts.of(i), scan);
            let hits: Vec<[f64; 3]> = hits.iter().map(|h| (h.coords + offset).into()).collect();
            write_ply(&dir.join(format!("vp_{:03}.ply", node.id)), t.into(), &hits)?;
        }
        std::fs::write(dir.join("poses.txt"), poses)
            .map_err(|e| Error::io(dir.join("poses.txt"), e))?;
        let readme = format!(
            "Scans exported by sigmap {version}: {what}.\n\
             What a real robot records: the measured ranges and the NOMINAL (believed) sensor\n\
             poses T_sw^-1 T_rw T_cr; never the truth.\n\n\
             Frames: the map frame is the scene frame shifted by the run's grid offset\n\
             {offset:?} m (zero unless the experiment sets grid_offset = true), as in\n\
             `sigmap run`; in the sensor frame the boresight is +z, horizontal angles turn\n\
             toward +x, vertical toward +y.\n\n\
             scans.graph  OctoMap ScanGraph (graph2tree, octovis): per viewpoint its pose\n\
             \x20            (map_from_sensor) and its end points in the SENSOR frame. A beam\n\
             \x20            that returned nothing is a point {reach} x max range ({far} m) away:\n\
             \x20            give graph2tree -m {max_range} and it clears free space up to the\n\
             \x20            maximum range, as sigmap's ray update does.\n\
             vp_NNN.ply   the hits of viewpoint NNN in the MAP frame (nominal pose applied);\n\
             \x20            vertex 0 (red) is the sensor origin.\n\
             poses.txt    TUM trajectory: timestamp tx ty tz qx qy qz qw of map_from_sensor,\n\
             \x20            the timestamp being the viewpoint index.\n\
             {depth}\n\
             OctoMap's map of these scans at the experiment's resolution, and its scores:\n\
             \x20 {command}\n\
             \x20 sigmap score map.bt.ot EXPERIMENT.toml --seed SEED [--cell K]\n\
             (score the .bt.ot graph2tree writes beside the .bt: it keeps the log-odds; the .bt\n\
             holds only occupied and free, so cells the scores call unknown are classified.)\n",
            offset = [offset.x, offset.y, offset.z],
            version = env!("CARGO_PKG_VERSION"),
            reach = NO_RETURN_REACH,
            far = NO_RETURN_REACH * view.max_range,
            max_range = view.max_range,
            command = graph2tree_command(Path::new("."), resolution, view.max_range),
            depth = camera.map_or(String::new(), |camera| depth_readme(camera, resolution)),
        );
        std::fs::write(dir.join("README.txt"), readme)
            .map_err(|e| Error::io(dir.join("README.txt"), e))
    })
}

/// The depth images of a pinhole sensor's `scans` in `dir`, in the TUM RGB-D
/// layout: `depth/vp_NNN.png` (16-bit, the raw depth `camera.scale` per
/// metre along the optical axis, 0 where a pixel measured nothing) listed in
/// `depth.txt` with the viewpoint index as timestamp, which `poses.txt`
/// gives each pose.
fn write_depth_images(
    dir: &Path,
    view: &MapperView,
    scans: &[Scan],
    camera: &DepthCamera,
) -> Result<()> {
    std::fs::create_dir_all(dir.join("depth")).map_err(|e| Error::io(dir.join("depth"), e))?;
    let mut list = String::from(
        "# depth images of sigmap's simulated depth camera (TUM RGB-D layout); timestamp = viewpoint index\n",
    );
    for (i, scan) in scans.iter().enumerate() {
        let layout = view.layouts.of(i);
        let Some(pixels) = &layout.pixels else {
            return Err(Error::Internal("a pinhole scan without its pixels".into()));
        };
        let mut depths = vec![0u16; pixels.columns * pixels.rows];
        for ((m, d), &slot) in scan
            .measurements
            .iter()
            .zip(&layout.directions)
            .zip(&pixels.slots)
        {
            if m.status == BeamStatus::Hit {
                let raw = (m.range * d.z * camera.scale).round();
                depths[slot as usize] = raw.clamp(1.0, f64::from(u16::MAX)) as u16;
            }
        }
        let name = format!("depth/vp_{:03}.png", scan.viewpoint);
        let png = depth_png(pixels.columns as u32, &depths).map_err(Error::Internal)?;
        std::fs::write(dir.join(&name), png).map_err(|e| Error::io(dir.join(&name), e))?;
        let _ = writeln!(list, "{} {name}", scan.viewpoint);
    }
    std::fs::write(dir.join("depth.txt"), list).map_err(|e| Error::io(dir.join("depth.txt"), e))
}

/// The README's lines on the depth images, with the `sigmap map` command
/// that maps them back at `resolution`.
fn depth_readme(camera: &DepthCamera, resolution: f64) -> String {
    let scale = if camera.scale == DepthCamera::TUM.scale {
        String::new()
    } else {
        format!(" --depth-scale {}", camera.scale)
    };
    format!(
        "depth/       the depth camera's images, TUM RGB-D layout (depth.txt lists them, the\n\
         \x20            timestamp being the viewpoint index): 16-bit PNG, {scale_value} per metre of\n\
         \x20            depth along the optical axis, 0 where a pixel measured nothing.\n\
         \x20            Intrinsics (px): fx {fx:?}, fy {fy:?},\n\
         \x20            cx {cx:?}, cy {cy:?}. Mapped by sigmap:\n\
         \x20              sigmap map --scans . --trajectory poses.txt \\\n\
         \x20                --intrinsics {fx:?},{fy:?},{cx:?},{cy:?}{scale} \\\n\
         \x20                --resolution {resolution} --profile PROFILE.toml --out map.ot\n\
         \x20            (a profile with the arm's error on the pose, not on the joints,\n\
         \x20            and the camera's error of its depth: experiments/profiles/\n\
         \x20            depth_camera_poses.toml, docs/math.md §5.6).\n",
        scale_value = camera.scale,
        fx = camera.fx,
        fy = camera.fy,
        cx = camera.cx,
        cy = camera.cy,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::{read_ply, simulate};

    #[test]
    fn each_ply_holds_its_viewpoints_measured_hits() {
        let experiment = crate::experiment::shipped_quickstart();
        let run = simulate(&experiment, 1, |_| {}).unwrap();
        let view = experiment.mapper_view();
        let offset = Vector3::new(0.004, -0.002, 0.001);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("export");
        let frame = MapFrame {
            resolution: 0.01,
            offset: &offset,
            camera: None,
        };
        write_export(&out, &view, &run.scans, &frame, "test").unwrap();
        // The profile drops 1% of the beams: the hits must still be the scan's.
        assert!(run.scans[0]
            .measurements
            .iter()
            .any(|m| m.status == BeamStatus::Dropout));
        for scan in &run.scans {
            let (origin, hits, _) = ray_inputs(&experiment.scanner().layout, scan);
            let (ply_origin, ply_hits) =
                read_ply(&out.join(format!("vp_{:03}.ply", scan.viewpoint))).unwrap();
            assert!((Vector3::from(ply_origin) - (origin.coords + offset)).norm() < 1e-12);
            assert_eq!(ply_hits.len(), hits.len());
            for (p, h) in ply_hits.iter().zip(&hits) {
                assert!((Vector3::from(*p) - (h.coords + offset)).norm() < 1e-9);
            }
        }
    }

    /// A depth camera's export holds its images in the TUM RGB-D layout:
    /// read back with the intrinsics the README gives and `poses.txt`, each
    /// viewpoint's image is its scan: the nominal pose, every hit on its
    /// pixel at its measured point (to the images' 0.2 mm depth steps), no
    /// other pixel.
    #[test]
    fn a_depth_cameras_images_read_back_as_its_scans() {
        use crate::experiment::run::depth_folder::{read_depth_folder, DepthImages};
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/depth_camera.toml");
        let experiment = crate::experiment::Experiment::load(&path).unwrap();
        let run = simulate(&experiment, 1, |_| {}).unwrap();
        let view = experiment.mapper_view();
        let offset = experiment.map_offset(1);
        let camera = experiment.scanner().camera.expect("a pinhole");
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("export");
        let frame = MapFrame {
            resolution: experiment.resolution(),
            offset: &offset,
            camera: Some(&camera),
        };
        write_export(&out, &view, &run.scans, &frame, "test").unwrap();
        let readme = std::fs::read_to_string(out.join("README.txt")).unwrap();
        let intrinsics = format!(
            "--intrinsics {:?},{:?},{:?},{:?}",
            camera.fx, camera.fy, camera.cx, camera.cy
        );
        assert!(readme.contains(&intrinsics), "{readme}");
        let options = DepthImages {
            camera,
            trajectory: Some(out.join("poses.txt")),
            every: 1,
        };
        let (nodes, notes) = read_depth_folder(&out, &options).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(nodes.len(), run.scans.len());
        let map_from_scene = Isometry3::translation(offset.x, offset.y, offset.z);
        let directions = &experiment.scanner().layout.directions;
        for (node, scan) in nodes.iter().zip(&run.scans) {
            let pose = map_from_scene * scan.chain.scene_from_camera();
            assert!((node.map_from_sensor.to_homogeneous() - pose.to_homogeneous()).norm() < 1e-9);
            let slots = &node.pixels.as_ref().expect("an image's pixels").slots;
            let hits = scan
                .measurements
                .iter()
                .filter(|m| m.status == BeamStatus::Hit);
            assert_eq!(slots.len(), hits.count());
            for (p, &slot) in node.points.iter().zip(slots) {
                let (m, d) = (&scan.measurements[slot as usize], directions[slot as usize]);
                assert_eq!(m.status, BeamStatus::Hit);
                let step = 0.5 / camera.scale / d.z;
                assert!((p.coords - d * m.range).norm() <= step * 1.000001, "{slot}");
            }
        }
    }
}
