//! A folder of depth images in the TUM RGB-D layout (depth.txt,
//! groundtruth.txt, 16-bit PNGs) given to `map --scans` and `score --scans`:
//! a floor seen from above by a Kinect-like camera at three heights and
//! turns maps onto the floor, and the floor scored against its scene agrees.

mod common;

use common::{refused, sigmap};
use std::path::Path;

/// The floor's top (m): mid-cell at 2 cm, so that no return sits on a
/// cell boundary.
const FLOOR_TOP: f64 = -0.01;

/// A 16-bit grayscale PNG, `width` x `height`, every pixel `depth`.
fn flat_png(width: u32, height: u32, depth: u16) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    let mut writer = encoder.write_header().unwrap();
    let row: Vec<u8> = (0..width).flat_map(|_| depth.to_be_bytes()).collect();
    writer
        .write_image_data(&row.repeat(height as usize))
        .unwrap();
    writer.finish().unwrap();
    bytes
}

/// The folder: a camera looking straight down (its z along the map's −z:
/// a half turn about x, then `yaw` about the vertical) from `height` above
/// the floor, so every pixel's depth is the height; 320 x 240 pixels
/// (half a Kinect's), TUM's depth scale.
fn write_folder(dir: &Path) {
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    let (mut list, mut trajectory) = (String::new(), String::new());
    for (k, (x, height, yaw)) in [(0.0, 1.0, 0.0), (0.2, 0.8, 0.5), (-0.1, 1.2, -1.0)]
        .into_iter()
        .enumerate()
    {
        let name = format!("depth/{k}.png");
        let raw = (height * 5000.0) as u16;
        std::fs::write(dir.join(&name), flat_png(320, 240, raw)).unwrap();
        let time = 1.0 + 0.1 * k as f64;
        list += &format!("{time:.6} {name}\n");
        // q = q_yaw(z) · q_half(x): (qx qy qz qw).
        let (s, c) = ((0.5f64 * yaw).sin(), (0.5f64 * yaw).cos());
        let (qx, qy, qz, qw) = (c, s, 0.0, 0.0);
        trajectory += &format!(
            "{:.6} {x} 0 {} {qx} {qy} {qz} {qw}\n",
            time + 0.004,
            FLOOR_TOP + height
        );
    }
    std::fs::write(dir.join("depth.txt"), list).unwrap();
    std::fs::write(dir.join("groundtruth.txt"), trajectory).unwrap();
}

#[test]
fn depth_images_map_onto_the_floor_they_saw() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = |p: &Path| p.display().to_string();
    let folder = d.join("rgbd");
    write_folder(&folder);
    // Half a Kinect: the TUM camera's focal lengths and centre halved.
    let intrinsics = "262.5,262.5,159.5,119.5";
    let scene = d.join("floor.toml");
    std::fs::write(
        &scene,
        format!(
            "[workspace]\nmin = [-1.5, -1.5, -0.2]\nmax = [1.5, 1.5, 1.4]\n\
             [[object]]\nname = \"floor\"\nshape = \"box\"\nsize = [4, 4, 0.1]\n\
             xyz = [0, 0, {}]\n",
            FLOOR_TOP - 0.05
        ),
    )
    .unwrap();
    let profile = path(&common::root().join("experiments/profiles/collaborative_poses.toml"));
    let folder_text = path(&folder);
    // `sigmap map` of the folder at 2 cm into `out`, with `extra` flags.
    let map_folder = |method: &str, out: &str, extra: &[&str]| {
        let head = ["map", "--scans", &folder_text, "--profile", &profile];
        let tail = ["--method", method, "--resolution", "0.02", "--out", out];
        sigmap(&[&head[..], extra, &tail].concat())
    };
    // Both methods, and the unscented map pooled on the images' pixels
    // (each pixel with its neighbours on the image, docs/math.md §5.6).
    let pooled: &[&str] = &["--beam-pooling", "windows"];
    for (method, name, extra) in [
        ("ray_update", "ray_update", &[][..]),
        ("unscented", "unscented", &[]),
        ("unscented", "pooled", pooled),
    ] {
        let map = path(&d.join(format!("{name}.ot")));
        let mapped = map_folder(
            method,
            &map,
            &[&["--intrinsics", intrinsics], extra].concat(),
        );
        let told = String::from_utf8_lossy(&mapped.stderr);
        assert!(mapped.status.success(), "{told}");
        assert!(
            told.contains("3 scans from") && told.contains("230400 beams"),
            "{told}"
        );
        let scored = sigmap(&[
            "score",
            &map,
            "--scene",
            &path(&scene),
            "--scans",
            &path(&folder),
            "--intrinsics",
            intrinsics,
        ]);
        let (stdout, stderr) = (
            String::from_utf8_lossy(&scored.stdout),
            String::from_utf8_lossy(&scored.stderr),
        );
        assert!(scored.status.success(), "{stderr}");
        // Every return lies on the floor where the trajectory puts it.
        assert!(stdout.contains("(100.0% of "), "{stdout}");
        assert!(!stderr.contains("warning"), "{stderr}");
        let metric = |name: &str| -> f64 {
            stdout
                .lines()
                .find_map(|l| l.trim().strip_prefix(name))
                .unwrap_or_else(|| panic!("{stdout}"))
                .trim()
                .parse()
                .unwrap()
        };
        assert!(metric("f1 ") > 0.99, "{name}: {stdout}");
        // The grids bin at the central pixel's angle: at the median
        // spacing of the points, bins between central pixels would stay
        // empty and leave 6.6% of the cells unknown (docs/math.md §5.6).
        if method == "unscented" {
            assert!(metric("unknown_fraction ") < 0.063, "{name}: {stdout}");
        }
    }
    // The floor scored raised 1.5 cm: the note moves it back down and names
    // what a floor leaves free.
    let raised = sigmap(&[
        "score",
        &path(&d.join("ray_update.ot")),
        "--scene",
        &path(&scene),
        "--scans",
        &folder_text,
        "--intrinsics",
        intrinsics,
        "--scene-pose",
        "0,0,0.015,0,0,0",
    ]);
    let told = String::from_utf8_lossy(&raised.stderr);
    assert!(
        told.contains("fix 3 of the 6 degrees of freedom and leave x, y and the turn about z free")
            && told.contains("(0.0000, 0.0000, -0.0150) m at")
            && told.contains("--scene-pose 0.0000,0.0000,0.0000,0.0000,0.0000,0.0000"),
        "{told}"
    );
    // The intrinsics are the ones given: TUM's own (twice the focal
    // lengths, the centre at the images' corner) put the points elsewhere.
    let tum = path(&d.join("tum.ot"));
    assert!(map_folder("ray_update", &tum, &["-q"]).status.success());
    let given = std::fs::read(d.join("ray_update.ot")).unwrap();
    assert!(std::fs::read(&tum).unwrap() != given);
    // Bad input: one line, exit 2.
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let x = path(&d.join("x.ot"));
    let run = |extra: &[&str], names: &str, says: &str| {
        let args = [
            &["map", "--scans"][..],
            extra,
            &["--profile", &profile, "--out", &x],
        ]
        .concat();
        refused(&args, names, says);
    };
    run(&[&path(&empty)], "empty", "is a folder without depth.txt");
    run(
        &[&path(&folder), "--every", "0"],
        "--every 0",
        "positive number of images",
    );
    run(
        &[&path(&folder), "--intrinsics", "0,1,2,3"],
        "--intrinsics",
        "nonzero focal lengths",
    );
    let trajectory = d.join("elsewhere.txt");
    std::fs::write(&trajectory, "50.0 0 0 0 0 0 0 1\n").unwrap();
    run(
        &[&path(&folder), "--trajectory", &path(&trajectory)],
        "elsewhere.txt",
        "none of the 3 images",
    );
    // Images with no depth anywhere (every pixel 0).
    let blank = d.join("blank");
    std::fs::create_dir_all(blank.join("depth")).unwrap();
    std::fs::write(blank.join("depth/0.png"), flat_png(4, 3, 0)).unwrap();
    std::fs::write(blank.join("depth.txt"), "1.0 depth/0.png\n").unwrap();
    std::fs::write(blank.join("groundtruth.txt"), "1.0 0 0 0 0 0 0 1\n").unwrap();
    run(&[&path(&blank)], "blank", "the depth images hold no depth");
    let log = d.join("scans.txt");
    std::fs::write(&log, "NODE 0 0 1 0 0 0\n0 0 1\n").unwrap();
    run(
        &[&path(&log), "--every", "2"],
        "scans.txt",
        "are for a folder of depth images",
    );
}
