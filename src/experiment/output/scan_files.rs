//! Scan files a user can open: per viewpoint a CSV of beams, a PLY point cloud
//! with the sensor origin, and the nominal chain in `sigmap propagate` format;
//! the truth in a separate folder for scoring.

use crate::error::{Error, Result};
use crate::experiment::{Experiment, SimulatedRun};
use crate::geometry::{Isometry3, Matrix6, Pose, Vector3};
use crate::mapping::depth_images::DepthCamera;
use crate::mapping::measured::{pooled_ray_ends, ray_inputs_into};
use crate::mapping::scan::{BeamStatus, MapperView, Scan};
use crate::sim::scan::ScanTruth;
use crate::uncertainty::UncertainPose;
use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

fn create(path: &Path) -> Result<std::io::BufWriter<std::fs::File>> {
    std::fs::File::create(path)
        .map(|f| std::io::BufWriter::with_capacity(1 << 16, f))
        .map_err(|e| Error::io(path, e))
}

fn put(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| Error::io(path, e))
}

fn finish(path: &Path, writer: std::io::BufWriter<std::fs::File>) -> Result<()> {
    writer
        .into_inner()
        .map_err(|e| Error::io(path, e.into_error()))?
        .sync_all()
        .map_err(|e| Error::io(path, e))
}

/// `[a, b, c]` with shortest round-trip floats.
fn list(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|v| format!("{v:?}")).collect();
    format!("[{}]", items.join(", "))
}

fn matrix6(m: &Matrix6) -> String {
    let rows: Vec<String> = (0..6)
        .map(|i| format!("  {}", list(&m.row(i).iter().copied().collect::<Vec<_>>())))
        .collect();
    format!("[\n{},\n]", rows.join(",\n"))
}

/// One `[[transform]]` of a chain file.
fn transform_entry(out: &mut String, name: &str, pose: &UncertainPose, inverse: bool) {
    let _ = writeln!(out, "[[transform]]\nname = \"{name}\"");
    let _ = writeln!(
        out,
        "xyz = {}\nrpy = {}",
        list(pose.mean.xyz.as_slice()),
        list(pose.mean.rpy.as_slice())
    );
    if inverse {
        let _ = writeln!(out, "inverse = true");
    }
    let _ = writeln!(out, "covariance = {}\n", matrix6(&pose.covariance));
}

/// The nominal chain of a scan in the `sigmap propagate` chain format
/// (without its `[point]`: add one to propagate a measurement).
pub fn chain_file(scan: &Scan) -> String {
    let mut out = String::from(
        "# X_scene = T_sw^-1 · T_rw · T_cr · X_camera (listed left to right); m, rad, m², rad².\n\
         # Add a [point] (xyz = [..], covariance or sigma) to run `sigmap propagate` on it.\n\n",
    );
    transform_entry(
        &mut out,
        "world_from_scene",
        &scan.chain.world_from_scene,
        true,
    );
    transform_entry(
        &mut out,
        "world_from_robot",
        &scan.chain.world_from_robot,
        false,
    );
    transform_entry(
        &mut out,
        "robot_from_camera",
        &scan.chain.robot_from_camera,
        false,
    );
    out
}

fn pose_line(out: &mut String, name: &str, iso: &Isometry3) {
    let pose = Pose::from_isometry(iso);
    let _ = writeln!(
        out,
        "{name} = {{ xyz = {}, rpy = {} }}",
        list(pose.xyz.as_slice()),
        list(pose.rpy.as_slice())
    );
}

/// `scan.toml`: what a scan set was simulated from (serde, so any name is
/// valid TOML).
#[derive(serde::Serialize)]
struct ScanManifest<'a> {
    experiment: &'a str,
    seed: u64,
    scene: &'a str,
    robot: &'a str,
    error_profile: &'a str,
    viewpoints: usize,
    beams_per_viewpoint: usize,
    rows: usize,
    columns: usize,
    min_range: f64,
    max_range: f64,
    /// The range model the maps are calibrated with (the profile's, as
    /// `[believed]` scales it).
    range: crate::uncertainty::RangeModel,
    /// What the maps are told of the profile's errors, when not what the
    /// simulator draws: the factors, and the believed profile's name when
    /// it is another profile.
    #[serde(skip_serializing_if = "Option::is_none")]
    believed: Option<BelievedTable<'a>>,
    /// A depth camera's intrinsics (px): pixel (column, row) looks along
    /// `((column − cx) / fx, (row − cy) / fy, 1)`; `scale`, the raw depth of
    /// a metre in its exported images.
    #[serde(skip_serializing_if = "Option::is_none")]
    pinhole: Option<&'a DepthCamera>,
}

/// `scan.toml`'s `[believed]` table.
#[derive(serde::Serialize)]
struct BelievedTable<'a> {
    /// The believed profile's name, when `[believed]` names one.
    #[serde(skip_serializing_if = "Option::is_none")]
    profile: Option<&'a str>,
    #[serde(flatten)]
    factors: &'a crate::sim::believed::BelievedErrors,
}

/// Writes every file of a simulated run into `dir` (which must exist).
pub fn write_scans(dir: &Path, experiment: &Experiment, run: &SimulatedRun) -> Result<()> {
    let truth_dir = dir.join("truth");
    std::fs::create_dir_all(&truth_dir).map_err(|e| Error::io(&truth_dir, e))?;
    let scanner = &experiment.scanner();
    let manifest = ScanManifest {
        experiment: experiment.name(),
        seed: run.seed,
        scene: &experiment.scene().name,
        robot: &experiment.robot().name,
        error_profile: &experiment.profile().name,
        viewpoints: run.scans.len(),
        beams_per_viewpoint: scanner.directions().len(),
        rows: scanner.rows,
        columns: scanner.columns,
        min_range: scanner.min_range,
        max_range: scanner.max_range,
        range: experiment.mapper_view().range,
        believed: Some(experiment.believed())
            .filter(|b| !b.is_calibrated())
            .map(|factors| BelievedTable {
                profile: factors
                    .profile
                    .as_ref()
                    .map(|_| experiment.believed_profile().name.as_str()),
                factors,
            }),
        pinhole: scanner.camera.as_ref(),
    };
    let manifest = format!(
        "# sigmap {} scan set; see docs/files.md, \"Scan files\".\n{}",
        env!("CARGO_PKG_VERSION"),
        toml::to_string(&manifest).map_err(|e| Error::Internal(format!("scan.toml: {e}")))?
    );
    put(&dir.join("scan.toml"), &manifest)?;

    let mut truth =
        String::from("# The true poses (scoring only: the modeller never sees these).\n");
    pose_line(&mut truth, "world_from_scene", &run.truth.world_from_scene);
    pose_line(
        &mut truth,
        "robot_from_camera",
        &run.truth.robot_from_camera,
    );
    for (v, iso) in run.truth.world_from_robot.iter().enumerate() {
        pose_line(
            &mut truth,
            &format!("viewpoint_{v:03}_world_from_robot"),
            iso,
        );
    }
    if experiment.profile().range.scale_sigma > 0.0 {
        for (v, scan) in run.truth.scans.iter().enumerate() {
            let _ = writeln!(truth, "viewpoint_{v:03}_range_scale = {}", scan.range_scale);
        }
    }
    put(&truth_dir.join("run.toml"), &truth)?;

    let summary_path = dir.join("viewpoints.csv");
    let mut summary =
        csv::Writer::from_path(&summary_path).map_err(|e| Error::io(&summary_path, e.into()))?;
    let dof = experiment.arm().dof();
    let mut header: Vec<String> = vec!["viewpoint".into(), "request".into()];
    header.extend((1..=dof).map(|j| format!("joint_{j}")));
    header.extend(["hits", "no_return", "too_close", "dropout"].map(String::from));
    summary
        .write_record(&header)
        .map_err(|e| Error::io(&summary_path, e.into()))?;
    for (scan, truth) in run.scans.iter().zip(&run.truth.scans) {
        write_viewpoint(dir, &truth_dir, scanner, scan, truth)?;
        let count = |s: BeamStatus| {
            scan.measurements
                .iter()
                .filter(|m| m.status == s)
                .count()
                .to_string()
        };
        let mut row = vec![
            scan.viewpoint.to_string(),
            experiment.viewpoints()[scan.viewpoint].request.clone(),
        ];
        row.extend(scan.joints.iter().map(|q| format!("{q:?}")));
        row.extend(
            [
                BeamStatus::Hit,
                BeamStatus::NoReturn,
                BeamStatus::TooClose,
                BeamStatus::Dropout,
            ]
            .map(count),
        );
        summary
            .write_record(&row)
            .map_err(|e| Error::io(&summary_path, e.into()))?;
    }
    summary.flush().map_err(|e| Error::io(&summary_path, e))
}

fn write_viewpoint(
    dir: &Path,
    truth_dir: &Path,
    scanner: &crate::sim::sensor::Scanner,
    scan: &Scan,
    scan_truth: &ScanTruth,
) -> Result<()> {
    let stem = format!("vp_{:03}", scan.viewpoint);
    put(&dir.join(format!("{stem}.chain.toml")), &chain_file(scan))?;
    let scene_from_camera = scan.chain.scene_from_camera();

    let csv_path = dir.join(format!("{stem}.csv"));
    let mut csv = create(&csv_path)?;
    let mut line = String::with_capacity(256);
    writeln!(csv, "beam,row,column,dir_x,dir_y,dir_z,status,range,camera_x,camera_y,camera_z,scene_x,scene_y,scene_z")
        .map_err(|e| Error::io(&csv_path, e))?;
    let mut cloud: Vec<[f64; 3]> = Vec::new();
    for (i, (m, d)) in scan
        .measurements
        .iter()
        .zip(scanner.directions())
        .enumerate()
    {
        line.clear();
        let _ = write!(
            line,
            "{i},{},{},{:?},{:?},{:?},{}",
            i / scanner.columns,
            i % scanner.columns,
            d.x,
            d.y,
            d.z,
            m.status.as_str()
        );
        if m.status == BeamStatus::Hit {
            let camera = d * m.range;
            let scene = scene_from_camera * nalgebra::Point3::from(camera);
            cloud.push([scene.x, scene.y, scene.z]);
            let _ = write!(
                line,
                ",{:?},{:?},{:?},{:?},{:?},{:?},{:?}",
                m.range, camera.x, camera.y, camera.z, scene.x, scene.y, scene.z
            );
        } else {
            line.push_str(",,,,,,,");
        }
        line.push('\n');
        csv.write_all(line.as_bytes())
            .map_err(|e| Error::io(&csv_path, e))?;
    }
    finish(&csv_path, csv)?;

    let origin = scene_from_camera.translation.vector;
    write_ply(
        &dir.join(format!("{stem}.ply")),
        [origin.x, origin.y, origin.z],
        &cloud,
    )?;

    let truth_path = truth_dir.join(format!("{stem}.csv"));
    let mut truth = create(&truth_path)?;
    writeln!(truth, "beam,true_range,true_x,true_y,true_z,object")
        .map_err(|e| Error::io(&truth_path, e))?;
    for (i, t) in scan_truth.beams.iter().enumerate() {
        line.clear();
        if t.range.is_nan() {
            let _ = writeln!(line, "{i},,,,,");
        } else {
            let _ = writeln!(
                line,
                "{i},{:?},{:?},{:?},{:?},{}",
                t.range, t.point.x, t.point.y, t.point.z, t.object
            );
        }
        truth
            .write_all(line.as_bytes())
            .map_err(|e| Error::io(&truth_path, e))?;
    }
    finish(&truth_path, truth)
}

/// A binary little-endian PLY: the sensor origin (red) then the points (grey),
/// in the scene frame, as CloudCompare and MeshLab read it.
pub fn write_ply(path: &Path, origin: [f64; 3], points: &[[f64; 3]]) -> Result<()> {
    let mut w = create(path)?;
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment sigmap scan in the scene frame; vertex 0 is the sensor origin\n\
         comment sensor_origin {:?} {:?} {:?}\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        origin[0],
        origin[1],
        origin[2],
        points.len() + 1
    );
    w.write_all(header.as_bytes())
        .map_err(|e| Error::io(path, e))?;
    let mut record = [0u8; 27];
    for (k, p) in std::iter::once(&origin).chain(points).enumerate() {
        for (c, v) in p.iter().enumerate() {
            record[c * 8..c * 8 + 8].copy_from_slice(&v.to_le_bytes());
        }
        record[24..].copy_from_slice(if k == 0 {
            &[255, 0, 0]
        } else {
            &[180, 180, 180]
        });
        w.write_all(&record).map_err(|e| Error::io(path, e))?;
    }
    finish(path, w)
}

/// Reads back a PLY written by [`write_ply`]: the sensor origin and the points.
pub fn read_ply(path: &Path) -> Result<([f64; 3], Vec<[f64; 3]>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let end = b"end_header\n";
    let split = bytes
        .windows(end.len())
        .position(|w| w == end)
        .ok_or_else(|| Error::input(path, "not a PLY file: no end_header"))?;
    let header = String::from_utf8_lossy(&bytes[..split]);
    let count: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .and_then(|n| n.trim().parse().ok())
        .ok_or_else(|| Error::input(path, "PLY without a vertex count"))?;
    let body = &bytes[split + end.len()..];
    if body.len() != count * 27 || count == 0 {
        return Err(Error::input(path, "PLY body does not match its header"));
    }
    let mut points: Vec<[f64; 3]> = body
        .chunks_exact(27)
        .map(|r| {
            std::array::from_fn(|c| {
                f64::from_le_bytes(r[c * 8..c * 8 + 8].try_into().unwrap_or([0; 8]))
            })
        })
        .collect();
    let origin = points.remove(0);
    Ok((origin, points))
}

/// The default output folder of `sigmap simulate`.
pub fn default_scan_dir(experiment: &Experiment) -> PathBuf {
    PathBuf::from("results")
        .join(experiment.name())
        .join("scans")
}

/// The rays OctoMap's `insertPointCloud` gets: per scan, the origin and the
/// end points (no-return beams as points at twice the maximum range, which
/// OctoMap truncates to free space); with `beam_pooling`, the pooled points,
/// as sigmap's ray update inserts them; in the map frame, the scene frame
/// shifted by `offset` (the run's grid offset). Little-endian:
/// `"SIGMAPRAYS1\n"`, `f32` max range, `u32` scans; per scan `f32` origin x y z,
/// `u32` n, n × `f32` x y z (benches/octomap/insert.cpp reads it).
pub fn write_rays(path: &Path, view: &MapperView, scans: &[Scan], offset: &Vector3) -> Result<()> {
    let mut out = b"SIGMAPRAYS1\n".to_vec();
    let max_range = view.max_range;
    out.extend_from_slice(&(max_range as f32).to_le_bytes());
    out.extend_from_slice(&(scans.len() as u32).to_le_bytes());
    let (mut hits, mut misses) = (Vec::new(), Vec::new());
    for (i, scan) in scans.iter().enumerate() {
        let layout = view.layouts.of(i);
        let pooled = pooled_ray_ends(view, layout, scan).map_err(Error::Usage)?;
        let origin =
            ray_inputs_into(layout, scan, pooled.as_deref(), &mut hits, &mut misses) + offset;
        for v in origin.iter() {
            out.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        out.extend_from_slice(&((hits.len() + misses.len()) as u32).to_le_bytes());
        let far = misses
            .iter()
            .map(|d| crate::mapping::ray_update::no_return_point(&origin, d, max_range));
        for p in hits.iter().map(|h| h + offset).chain(far) {
            for v in p.iter() {
                out.extend_from_slice(&(*v as f32).to_le_bytes());
            }
        }
    }
    crate::files::write_file(path, &out)
}
