//! One simulated run: the truth draw and a scan per viewpoint.

use crate::error::{Error, Result};
use crate::experiment::Experiment;
use crate::geometry::Isometry3;
use crate::mapping::scan::{NominalChain, Scan};
use crate::sim::scan::{cast_beams, frame_scale, ScanTruth};
use crate::sim::streams::{Stream, Streams};
use crate::sim::truth::{arm_covariance, draw_arm, draw_pose};
use crate::uncertainty::UncertainPose;

/// The truth of a run, for scoring only: the draws of the run and of each
/// viewpoint, and what really happened to every beam.
#[derive(Clone, Debug)]
pub struct RunTruth {
    /// The true `world_from_scene`.
    pub world_from_scene: Isometry3,
    /// The true `robot_from_camera`.
    pub robot_from_camera: Isometry3,
    /// The true `world_from_robot` of each viewpoint.
    pub world_from_robot: Vec<Isometry3>,
    /// The truth behind each scan, in the order of `SimulatedRun::scans`.
    pub scans: Vec<ScanTruth>,
}

/// Everything one run produced.
#[derive(Clone, Debug)]
pub struct SimulatedRun {
    /// The seed of the run.
    pub seed: u64,
    /// One scan per viewpoint: what a mapper may see.
    pub scans: Vec<Scan>,
    /// Scoring only; never given to map building.
    pub truth: RunTruth,
}

/// Simulates every viewpoint of `experiment` with `seed`. `progress` is called
/// after each viewpoint.
pub fn simulate(
    experiment: &Experiment,
    seed: u64,
    mut progress: impl FnMut(usize),
) -> Result<SimulatedRun> {
    let streams = Streams::new(seed);
    let profile = &experiment.profile();
    let world_from_scene = UncertainPose {
        mean: experiment.world_from_scene(),
        covariance: profile.world_from_scene,
    };
    let robot_from_camera = UncertainPose {
        mean: experiment.robot_from_camera(),
        covariance: profile.robot_from_camera,
    };
    let mut run_rng = streams.rng(Stream::Run);
    // What each scan states of its pose errors: the believed profile's
    // covariances times the factor's square ([believed]).
    let told = experiment.believed_profile();
    let told_variance = experiment.believed().pose_variance();
    let told_world_from_scene = experiment.told_world_from_scene();
    let told_robot_from_camera = told.robot_from_camera * told_variance;
    let true_world_from_scene = draw_pose(&world_from_scene, &mut run_rng).to_isometry();
    let true_robot_from_camera = draw_pose(&robot_from_camera, &mut run_rng).to_isometry();
    let mut scans = Vec::with_capacity(experiment.viewpoints().len());
    let mut true_arm = Vec::with_capacity(experiment.viewpoints().len());
    let mut true_scans = Vec::with_capacity(experiment.viewpoints().len());
    for (index, viewpoint) in experiment.viewpoints().iter().enumerate() {
        let mut rng = streams.rng(Stream::Viewpoint(index as u32));
        let arm = draw_arm(
            &profile.arm,
            experiment.arm(),
            &experiment.world_from_base(),
            &viewpoint.joints,
            &mut rng,
        )
        .map_err(|e| {
            Error::input(
                experiment.source(),
                format!("viewpoint {index} ({}): {e}", viewpoint.request),
            )
        })?;
        // What the scan states of the arm's error: the believed arm's at
        // these joints (for a calibrated belief, the drawn arm's to the bit).
        let told_arm = arm_covariance(
            &told.arm,
            experiment.arm(),
            &experiment.world_from_base(),
            &viewpoint.joints,
        )
        .map_err(|e| {
            Error::input(
                &told.source,
                format!("viewpoint {index} ({}): {e}", viewpoint.request),
            )
        })?;
        let scene_from_camera =
            true_world_from_scene.inverse() * arm.truth * true_robot_from_camera;
        let (measurements, beams) = cast_beams(
            experiment.scene(),
            experiment.scanner(),
            &profile.range,
            &scene_from_camera,
            &streams,
            index as u32,
        );
        // Each scan states its pose errors as the maps are told them.
        scans.push(Scan {
            viewpoint: index,
            joints: viewpoint.joints.clone(),
            chain: NominalChain {
                world_from_scene: told_world_from_scene,
                world_from_robot: UncertainPose {
                    mean: arm.believed.mean,
                    covariance: told_arm * told_variance,
                },
                robot_from_camera: UncertainPose {
                    mean: robot_from_camera.mean,
                    covariance: told_robot_from_camera,
                },
            },
            measurements,
        });
        true_scans.push(ScanTruth {
            scene_from_camera,
            range_scale: frame_scale(&profile.range, &streams, index as u32),
            beams,
        });
        true_arm.push(arm.truth);
        progress(index + 1);
    }
    Ok(SimulatedRun {
        seed,
        scans,
        truth: RunTruth {
            world_from_scene: true_world_from_scene,
            robot_from_camera: true_robot_from_camera,
            world_from_robot: true_arm,
            scans: true_scans,
        },
    })
}
