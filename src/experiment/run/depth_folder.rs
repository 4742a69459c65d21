//! A folder of depth images with their trajectory (the TUM RGB-D layout,
//! `mapping::depth_images`) read as recorded scans (`sigmap map --scans
//! DIR`, `sigmap score --scans DIR`).

use super::recorded::MAX_RECORDED_POINTS;
use crate::error::{Error, Result};
use crate::mapping::depth_images::{
    associate, depth_image_node, parse_depth_list, parse_trajectory, DepthCamera, MAX_TIME_GAP,
};
use crate::mapping::scan::MAX_BEAMS_PER_VIEWPOINT;
use crate::mapping::scan_graph::ScanNode;
use rayon::prelude::*;
use std::io::Read as _;
use std::path::{Path, PathBuf};

/// How a folder of depth images is read.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthImages {
    /// The camera.
    pub camera: DepthCamera,
    /// The trajectory file; `None`: the folder's `groundtruth.txt`.
    pub trajectory: Option<PathBuf>,
    /// Read every this many images (of those with a pose), from the first.
    pub every: usize,
}

impl Default for DepthImages {
    fn default() -> Self {
        Self {
            camera: DepthCamera::TUM,
            trajectory: None,
            every: 1,
        }
    }
}

/// The largest list or trajectory file read (bytes).
const MAX_LIST_BYTES: u64 = 1 << 30;

/// The largest depth image file read (bytes).
const MAX_IMAGE_BYTES: u64 = 256 << 20;

/// The nodes of the depth images of the folder `dir` (its `depth.txt`),
/// each at the trajectory's pose nearest its time, with notes for the
/// images left without one. Every image is checked (its size from its
/// header) before any is decoded.
pub fn read_depth_folder(
    dir: &Path,
    options: &DepthImages,
) -> Result<(Vec<ScanNode>, Vec<String>)> {
    options.camera.check().map_err(Error::Usage)?;
    if options.every == 0 {
        return Err(Error::Usage(
            "--every 0: give a positive number of images".into(),
        ));
    }
    let list_path = dir.join("depth.txt");
    if !list_path.is_file() {
        return Err(Error::input(
            dir,
            "is a folder without depth.txt: --scans takes an OctoMap ScanGraph, a scan log, or \
             a folder of depth images in the TUM RGB-D layout (depth.txt, groundtruth.txt or \
             --trajectory, depth/*.png)",
        ));
    }
    let images = parse_depth_list(&read_text(&list_path)?)
        .map_err(|e| Error::input(&list_path, format!("not a depth image list: {e}")))?;
    let trajectory_path = options
        .trajectory
        .clone()
        .unwrap_or_else(|| dir.join("groundtruth.txt"));
    if options.trajectory.is_none() && !trajectory_path.exists() {
        return Err(Error::input(
            dir,
            "has no groundtruth.txt: give the camera's trajectory with --trajectory FILE \
             (`timestamp tx ty tz qx qy qz qw` lines, e.g. a SLAM system's estimate)",
        ));
    }
    let poses = parse_trajectory(&read_text(&trajectory_path)?).map_err(|e| {
        Error::input(
            &trajectory_path,
            format!("not a trajectory (timestamp tx ty tz qx qy qz qw): {e}"),
        )
    })?;
    let times: Vec<f64> = images.iter().map(|(t, _)| *t).collect();
    let matched = associate(&times, &poses);
    let posed: Vec<(usize, usize)> = matched
        .iter()
        .enumerate()
        .filter_map(|(image, pose)| pose.map(|p| (image, p)))
        .collect();
    let unposed = images.len() - posed.len();
    if posed.is_empty() {
        return Err(Error::input(
            &trajectory_path,
            format!(
                "none of the {} images of {} has a pose within {MAX_TIME_GAP} s of its time: \
                 is this the trajectory of these images?",
                images.len(),
                list_path.display()
            ),
        ));
    }
    let selected: Vec<(usize, usize)> = posed.into_iter().step_by(options.every).collect();
    let file_of = |image: usize| dir.join(&images[image].1);
    // Each image's size from its header, before anything is decoded.
    let mut pixels = 0u64;
    for &(image, _) in &selected {
        let path = file_of(image);
        let (width, height) = png_size(&path)?;
        let count = u64::from(width) * u64::from(height);
        if count as f64 > MAX_BEAMS_PER_VIEWPOINT {
            return Err(Error::input(
                &path,
                format!(
                    "{width} x {height} pixels: sigmap maps at most \
                     {MAX_BEAMS_PER_VIEWPOINT:.0} beams a scan"
                ),
            ));
        }
        pixels += count;
        if pixels > MAX_RECORDED_POINTS {
            return Err(Error::input(
                &list_path,
                format!(
                    "the {} images selected hold more than {MAX_RECORDED_POINTS} pixels, more \
                     points than sigmap maps at once (about 80 bytes each while mapping): read \
                     fewer images with --every N",
                    selected.len()
                ),
            ));
        }
    }
    let nodes = selected
        .par_iter()
        .enumerate()
        .map(|(id, &(image, pose))| {
            let path = file_of(image);
            let bytes = read_bytes(&path, MAX_IMAGE_BYTES)?;
            let id = u32::try_from(id).map_err(|_| Error::input(&list_path, "too many images"))?;
            depth_image_node(&bytes, &options.camera, id, poses[pose].1)
                .map_err(|e| Error::input(&path, e))
        })
        .collect::<Vec<_>>()
        // The first image's error in file order, whatever the threads did.
        .into_iter()
        .collect::<Result<Vec<_>>>()?;
    let mut notes = Vec::new();
    if unposed > 0 {
        notes.push(format!(
            "note: {unposed} of the {} images of {} have no pose within {MAX_TIME_GAP} s of \
             their time in {} and are left out",
            images.len(),
            list_path.display(),
            trajectory_path.display()
        ));
    }
    Ok((nodes, notes))
}

/// The text of `path`, refused past [`MAX_LIST_BYTES`].
fn read_text(path: &Path) -> Result<String> {
    let bytes = read_bytes(path, MAX_LIST_BYTES)?;
    String::from_utf8(bytes).map_err(|_| Error::input(path, "is not text (invalid UTF-8)"))
}

/// The bytes of the regular file `path`, refused past `limit`.
fn read_bytes(path: &Path, limit: u64) -> Result<Vec<u8>> {
    let meta =
        std::fs::metadata(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    if !meta.is_file() {
        return Err(Error::input(path, "is not a regular file"));
    }
    if meta.len() > limit {
        return Err(Error::input(
            path,
            format!("{} bytes: more than the {limit} sigmap reads", meta.len()),
        ));
    }
    std::fs::read(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))
}

/// Width and height of the PNG at `path`, from its first chunk (the PNG
/// standard puts `IHDR` first: signature, length, type, width, height).
fn png_size(path: &Path) -> Result<(u32, u32)> {
    let mut head = Vec::with_capacity(24);
    std::fs::File::open(path)
        .and_then(|f| f.take(24).read_to_end(&mut head))
        .map_err(|e| Error::input(path, format!("cannot read the depth image: {e}")))?;
    const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
    if head.len() < 24 || head[..8] != SIGNATURE || &head[12..16] != b"IHDR" {
        return Err(Error::input(path, "is not a PNG image"));
    }
    let number =
        |at: usize| u32::from_be_bytes([head[at], head[at + 1], head[at + 2], head[at + 3]]);
    Ok((number(16), number(20)))
}

#[cfg(test)]
mod tests;
