//! `sigmap ground-truth`: a scene's true occupancy as an OctoMap file.

use super::{resolution_arg, spinner, GroundTruthArgs};
use crate::error::Result;
use crate::eval::ground_truth::{cell_counts, voxelise};
use crate::mapping::octomap_io::{check_octree_path, write_octree};
use crate::mapping::Clamp;
use crate::sim::scene::Scene;
use std::time::Instant;

/// `sigmap ground-truth`.
pub(crate) fn run(args: GroundTruthArgs) -> Result<()> {
    resolution_arg(args.resolution)?;
    check_octree_path(&args.out)?;
    let scene = Scene::load(&args.scene)?;
    super::print_notes(scene.notes(), false);
    scene.check_resolution(args.resolution)?;
    scene.check_truth_region(&scene.workspace, args.resolution, "the whole workspace")?;
    let start = Instant::now();
    let voxelising = spinner(&format!("voxelising '{}'", scene.name), false);
    let truth = voxelise(&scene, args.resolution);
    voxelising.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    write_octree(&args.out, &truth, Clamp::OCTOMAP)?;
    let (occupied, free) = cell_counts(&truth);
    eprintln!(
        "ground truth of '{}' at {} m: {occupied} occupied and {free} free cells ({} tree nodes) in {seconds:.2} s; wrote {}",
        scene.name,
        args.resolution,
        truth.stats().nodes,
        args.out.display()
    );
    Ok(())
}
