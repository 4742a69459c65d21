use super::*;
use crate::experiment::output::export::scan_nodes;
use crate::experiment::run::recorded::recorded_scans;
use crate::experiment::shipped_quickstart as quickstart;
use crate::experiment::{simulate, Experiment};
use crate::geometry::{Isometry3, Point3, Vector3};
use crate::mapping::depth_images::depth_png;
use crate::mapping::measured::measured_ranges;
use crate::mapping::pooling::Pooling;
use crate::mapping::{Layouts, MapSettings, MapperView};
use crate::uncertainty::{RangeModel, SigmaSet};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

/// A small depth camera: 80 x 60 pixels, about 60° across (unequal focal
/// lengths, so that rows and columns cannot be swapped unseen).
const CAMERA: DepthCamera = DepthCamera {
    fx: 70.0,
    fy: 65.0,
    cx: 39.5,
    cy: 29.5,
    scale: 5000.0,
};
const SIZE: (usize, usize) = (80, 60);

/// The quickstart's scene seen by [`CAMERA`] from its run's (believed)
/// sensor poses, written as a TUM RGB-D folder in `dir`: one image a
/// viewpoint at 1 + k/10 s, the trajectory 5 ms later, and one more image at
/// 100 s that no pose is near. Depths are quantised as the driver would,
/// after `noise`'s range error (seeded) is added along each pixel's ray.
fn write_folder(experiment: &Experiment, dir: &Path, noise: Option<&RangeModel>) -> Vec<Isometry3> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let run = simulate(experiment, 1, |_| {}).unwrap();
    let offset = experiment.map_offset(1);
    let nodes = scan_nodes(&experiment.mapper_view(), &run.scans, &offset);
    let scene_from_map = Isometry3::translation(-offset.x, -offset.y, -offset.z);
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    let (mut list, mut trajectory) = (String::from("# depth maps\n"), String::from("# gt\n"));
    let poses: Vec<Isometry3> = nodes.iter().map(|n| n.map_from_sensor).collect();
    for (k, pose) in poses.iter().chain([&poses[0]]).enumerate() {
        let scene_from_sensor = scene_from_map * pose;
        let depths: Vec<u16> = (0..SIZE.0 * SIZE.1)
            .map(|i| {
                let (u, v) = ((i % SIZE.0) as f64, (i / SIZE.0) as f64);
                let ray = Vector3::new(
                    (u - CAMERA.cx) / CAMERA.fx,
                    (v - CAMERA.cy) / CAMERA.fy,
                    1.0,
                );
                let direction = scene_from_sensor * ray.normalize();
                let origin = scene_from_sensor * Point3::origin();
                let mut error = |t: f64| {
                    noise.map_or(0.0, |n| {
                        n.sigma(&ray.normalize(), t) * rng.sample::<f64, _>(StandardNormal)
                    })
                };
                experiment
                    .scene()
                    .cast_ray(&origin, &direction, 4.0)
                    .map_or(0, |(t, _)| {
                        ((t + error(t)) / ray.norm() * CAMERA.scale).round() as u16
                    })
            })
            .collect();
        let name = format!("depth/{k:03}.png");
        std::fs::write(dir.join(&name), depth_png(SIZE.0 as u32, &depths).unwrap()).unwrap();
        let time = if k < poses.len() {
            1.0 + k as f64 / 10.0
        } else {
            100.0
        };
        list += &format!("{time:.6} {name}\n");
        if k < poses.len() {
            let (t, q) = (pose.translation.vector, pose.rotation.coords);
            trajectory += &format!(
                "{:.6} {} {} {} {} {} {} {}\n",
                time + 0.005,
                t.x,
                t.y,
                t.z,
                q.x,
                q.y,
                q.z,
                q.w
            );
        }
    }
    std::fs::write(dir.join("depth.txt"), list).unwrap();
    std::fs::write(dir.join("groundtruth.txt"), trajectory).unwrap();
    poses
}

#[test]
fn depth_pixels_land_on_the_surfaces_they_saw() {
    // Each image's points, placed by the trajectory, lie on the scene where
    // its pixel's ray met it: within the depth's quantisation (0.1 mm in
    // depth, at most 0.15 mm along the ray here).
    let dir = tempfile::tempdir().unwrap();
    let experiment = quickstart();
    let poses = write_folder(&experiment, dir.path(), None);
    let options = DepthImages {
        camera: CAMERA,
        ..DepthImages::default()
    };
    let (nodes, notes) = read_depth_folder(dir.path(), &options).unwrap();
    assert_eq!(nodes.len(), poses.len());
    assert_eq!(notes.len(), 1);
    assert!(notes[0].contains("1 of the 7 images"), "{notes:?}");
    let offset = experiment.map_offset(1);
    let mut checked = 0;
    for (node, pose) in nodes.iter().zip(&poses) {
        let read = node.map_from_sensor;
        assert!((read.translation.vector - pose.translation.vector).norm() < 1e-12);
        for p in &node.points {
            let (origin, end) = (read * Point3::origin() - offset, read * p - offset);
            let range = (end - origin).norm();
            let (t, _) = experiment
                .scene()
                .cast_ray(&origin, &((end - origin) / range), 4.0)
                .unwrap();
            assert!((t - range).abs() < 1.5e-4, "{t} against {range}");
            checked += 1;
        }
    }
    assert!(checked > 10_000, "{checked}");
    // Every other image: the first, third and fifth.
    let every = DepthImages {
        every: 2,
        ..options
    };
    let (some, _) = read_depth_folder(dir.path(), &every).unwrap();
    assert_eq!(some.len(), 3);
    assert_eq!(some[1].map_from_sensor, nodes[2].map_from_sensor);
    assert_eq!(some[1].points, nodes[2].points);
}

/// Pooling (§5.5) works on an image's pixels, each pooled with its
/// neighbours on the image: with the profile's range noise drawn into the
/// depths, most pixels of the quickstart's surfaces are pooled and their
/// pooled ranges lie nearer the surface than their raw ones (a 3 x 3
/// window averages nine ranges: a third of the error on a plane).
#[test]
fn depth_pixels_pool_with_their_neighbours_on_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let experiment = quickstart();
    let profile = crate::experiment::shipped_poses_profile();
    write_folder(&experiment, dir.path(), Some(&profile.range));
    let options = DepthImages {
        camera: CAMERA,
        ..DepthImages::default()
    };
    let (nodes, _) = read_depth_folder(dir.path(), &options).unwrap();
    let (scans, layouts) =
        recorded_scans(&nodes, &profile, f64::INFINITY, Some(CAMERA.angular_step())).unwrap();
    let settings = MapSettings {
        beam_pooling: Pooling::Windows,
        ..MapSettings::default()
    };
    let view = MapperView {
        layouts: Layouts::PerScan(&layouts),
        range: profile.range,
        max_range: f64::INFINITY,
        settings: &settings,
        sigma_set: SigmaSet::Paper,
    };
    let offset = experiment.map_offset(1);
    let (mut raw, mut pooled, mut count, mut hits) = (0.0, 0.0, 0, 0);
    for ((node, scan), layout) in nodes.iter().zip(&scans).zip(&layouts) {
        let ranges = measured_ranges(&view, layout, scan).unwrap();
        let origin = node.map_from_sensor * Point3::origin() - offset;
        for (p, range) in node.points.iter().zip(&ranges) {
            hits += 1;
            let Some(range) = range.filter(|r| r.normal.is_some()) else {
                continue;
            };
            let direction = node.map_from_sensor * (p.coords / p.coords.norm());
            let (t, _) = experiment
                .scene()
                .cast_ray(&origin, &direction, 4.0)
                .unwrap();
            raw += (p.coords.norm() - t).powi(2);
            pooled += (range.range - t).powi(2);
            count += 1;
        }
    }
    assert!(count * 10 > hits * 6, "{count} of {hits} pooled");
    let (raw, pooled) = ((raw / count as f64).sqrt(), (pooled / count as f64).sqrt());
    assert!(pooled < 0.5 * raw, "pooled rms {pooled} against raw {raw}");
}

#[test]
fn bad_folders_get_one_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let read = |options: &DepthImages| read_depth_folder(d, options).unwrap_err().to_string();
    let options = DepthImages::default();
    assert!(
        read(&options).contains("is a folder without depth.txt"),
        "{}",
        read(&options)
    );
    std::fs::create_dir_all(d.join("depth")).unwrap();
    std::fs::write(d.join("depth.txt"), "1.0 depth/a.png\n").unwrap();
    let e = read(&options);
    assert!(
        e.contains("has no groundtruth.txt: give") && e.contains("--trajectory"),
        "{e}"
    );
    let absent = DepthImages {
        trajectory: Some(d.join("absent.txt")),
        ..options.clone()
    };
    let e = read(&absent);
    assert!(e.contains("absent.txt: cannot read"), "{e}");
    std::fs::write(d.join("groundtruth.txt"), "5.0 0 0 0 0 0 0 1\n").unwrap();
    let e = read(&options);
    assert!(
        e.contains("none of the 1 images") && e.contains("within 0.02 s"),
        "{e}"
    );
    std::fs::write(d.join("groundtruth.txt"), "1.0 0 0 0 0 0 0 1\n").unwrap();
    let e = read(&options);
    assert!(e.contains("a.png") && e.contains("cannot read"), "{e}");
    std::fs::write(d.join("depth/a.png"), b"GIF89a, not a png at all").unwrap();
    let e = read(&options);
    assert!(e.contains("a.png: is not a PNG image"), "{e}");
    // A header claiming 100 000 x 100 000 pixels: refused before decoding.
    let mut huge = depth_png(1, &[1]).unwrap();
    huge[16..20].copy_from_slice(&100_000u32.to_be_bytes());
    huge[20..24].copy_from_slice(&100_000u32.to_be_bytes());
    std::fs::write(d.join("depth/a.png"), &huge).unwrap();
    let e = read(&options);
    assert!(e.contains("100000 x 100000 pixels"), "{e}");
    // Thirty images whose headers say 2000 x 2000 pixels: 1.2e8 in all,
    // refused from the headers alone (the files hold no pixels).
    let mut big = depth_png(1, &[1]).unwrap();
    big[16..20].copy_from_slice(&2000u32.to_be_bytes());
    big[20..24].copy_from_slice(&2000u32.to_be_bytes());
    let (mut list, mut poses) = (String::new(), String::new());
    for k in 0..30 {
        std::fs::write(d.join(format!("depth/{k}.png")), &big).unwrap();
        list += &format!("{k} depth/{k}.png\n");
        poses += &format!("{k} 0 0 0 0 0 0 1\n");
    }
    let many = d.join("many");
    std::fs::create_dir_all(&many).unwrap();
    std::fs::write(many.join("depth.txt"), list).unwrap();
    std::fs::write(many.join("groundtruth.txt"), poses).unwrap();
    std::fs::rename(d.join("depth"), many.join("depth")).unwrap();
    let e = read_depth_folder(&many, &options).unwrap_err().to_string();
    assert!(
        e.contains("depth.txt") && e.contains("the 30 images selected") && e.contains("--every N"),
        "{e}"
    );
    let halves = DepthImages {
        every: 2,
        ..options.clone()
    };
    let e = read_depth_folder(&many, &halves).unwrap_err().to_string();
    assert!(
        e.contains("depth/0.png") && e.contains("not a PNG image"),
        "{e}"
    );
    std::fs::create_dir_all(d.join("depth")).unwrap();
    std::fs::write(d.join("depth/a.png"), depth_png(2, &[0, 0]).unwrap()).unwrap();
    let (nodes, notes) = read_depth_folder(d, &options).unwrap();
    assert!(nodes[0].points.is_empty() && notes.is_empty());
    let e = read(&DepthImages {
        every: 0,
        ..options.clone()
    });
    assert!(e.contains("--every 0"), "{e}");
    let flat = DepthCamera {
        scale: -1.0,
        ..DepthCamera::TUM
    };
    let e = read(&DepthImages {
        camera: flat,
        ..options
    });
    assert!(e.contains("--depth-scale -1"), "{e}");
}
