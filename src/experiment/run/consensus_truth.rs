//! The truth as the scans, taken together, place it (docs/math.md §7.5,
//! "What the scans cannot undo"): the reference method `consensus_truth`.
//!
//! Each viewpoint's believed chain places the scene by the registration's
//! error and by its own arm and hand-eye errors. The views can be aligned
//! to one another from the scans, but a motion shared by all of them leaves
//! the scans consistent, as the registration's error does: no map built
//! from the scans alone can undo it. `consensus_truth` is the truth moved by the
//! registration's error and by the views' mean displacement, the placement
//! the views agree on when each is moved by no more than it must.

use super::runner::registered_placement;
use crate::eval::ground_truth::{voxelise_within, KeyBox};
use crate::experiment::{Experiment, RunTruth};
use crate::geometry::{Isometry3, Vector3};
use crate::mapping::octree::Octree;
use crate::mapping::Scan;

/// The displacement of each scan's believed placement of the scene from the
/// registration's alone, in the believed scene frame: `D_i = (T̂_sw⁻¹ T̂_rw,i
/// T̂_cr) (T̂_sw⁻¹ T_rw,i T_cr)⁻¹`, identity when the arm and the hand-eye
/// calibration are exact.
pub fn view_displacements(scans: &[Scan], truth: &RunTruth) -> Vec<Isometry3> {
    scans
        .iter()
        .zip(&truth.world_from_robot)
        .map(|(scan, world_from_robot)| {
            let registered = scan.chain.world_from_scene.mean.to_isometry().inverse()
                * world_from_robot
                * truth.robot_from_camera;
            scan.chain.scene_from_camera() * registered.inverse()
        })
        .collect()
}

/// The mean of `displacements`: the mean translation and the mean rotation
/// vector (their first-order mean: the displacements are small rotations).
/// Identity for none.
pub fn mean_displacement(displacements: &[Isometry3]) -> Isometry3 {
    if displacements.is_empty() {
        return Isometry3::identity();
    }
    let n = displacements.len() as f64;
    let translation: Vector3 = displacements
        .iter()
        .map(|d| d.translation.vector)
        .sum::<Vector3>()
        / n;
    let rotation: Vector3 = displacements
        .iter()
        .map(|d| d.rotation.scaled_axis())
        .sum::<Vector3>()
        / n;
    Isometry3::new(translation, rotation)
}

/// Where the scans together place the scene in the map frame: `map_from_scene
/// = offset · D̄ · T̂_sw⁻¹ T_sw`, `D̄` the views' [`mean_displacement`].
pub fn consensus_placement(
    experiment: &Experiment,
    scans: &[Scan],
    truth: &RunTruth,
    offset: &Vector3,
) -> Isometry3 {
    let shift = Isometry3::translation(offset.x, offset.y, offset.z);
    let mean = mean_displacement(&view_displacements(scans, truth));
    shift * mean * shift.inverse() * registered_placement(experiment, truth, offset)
}

/// The reference method `consensus_truth`: the truth at [`consensus_placement`],
/// computed over the finest cells of `region` (every other one unknown).
/// The registered truth when the arm and the hand-eye calibration are exact.
pub fn consensus_truth(
    experiment: &Experiment,
    scans: &[Scan],
    truth: &RunTruth,
    offset: &Vector3,
    region: &KeyBox,
) -> Octree {
    let map_from_scene = consensus_placement(experiment, scans, truth, offset);
    voxelise_within(
        experiment.scene(),
        experiment.resolution(),
        &map_from_scene,
        region,
    )
}

/// Test support: the run's true hits as the nominal chains place them in the
/// map frame (off cell faces, within `TOUCH`), counted over the cells where
/// `reference` holds a value: (hits, of those in `reference`'s occupied cells,
/// in `other`'s).
#[cfg(test)]
pub(crate) fn hits_placed_by_the_nominal_chain(
    experiment: &Experiment,
    run: &crate::experiment::SimulatedRun,
    offset: &Vector3,
    (reference, other): (&Octree, &Octree),
) -> (usize, usize, usize) {
    use crate::eval::ground_truth::TOUCH;
    use crate::geometry::Point3;
    use crate::mapping::octomap_io::is_occupied;
    use crate::mapping::octree::DEPTH;
    let resolution = reference.resolution();
    let (mut hits, mut in_reference, mut in_other) = (0, 0, 0);
    for (scan, seen) in run.scans.iter().zip(&run.truth.scans) {
        let map_from_camera = scan.chain.scene_from_camera();
        for (beam, d) in seen.beams.iter().zip(experiment.scanner().directions()) {
            if !beam.range.is_finite() {
                continue;
            }
            let point = map_from_camera * Point3::from(d * beam.range) + offset;
            // A surface point is inside its cell's solid unless it lies on a
            // cell face (within TOUCH): those are left out.
            let cell = (point.coords / resolution).map(|x| x - x.floor());
            if cell
                .iter()
                .any(|&f| f * resolution < 2.0 * TOUCH || (1.0 - f) * resolution < 2.0 * TOUCH)
            {
                continue;
            }
            let value = |tree: &Octree| tree.key(&point).and_then(|k| tree.query(&k, DEPTH));
            // Cells whose centre the error moves out of the workspace have
            // no truth.
            let Some(reference_value) = value(reference) else {
                continue;
            };
            hits += 1;
            in_reference += usize::from(is_occupied(reference_value));
            in_other += usize::from(value(other).is_some_and(is_occupied));
        }
    }
    (hits, in_reference, in_other)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::run::runner::{quickstart_with_profile, registered_truth};
    use crate::experiment::simulate;

    /// The quickstart under `profile` (a profile file's body), with its
    /// first `views` viewpoints only.
    fn quickstart(dir: &std::path::Path, profile: &str, views: usize) -> Experiment {
        quickstart_with_profile(dir, profile, "");
        let path = dir.join("experiment.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let kept: String = text
            .split_inclusive("[[viewpoint]]")
            .take(views + 1)
            .collect();
        let kept = kept.strip_suffix("[[viewpoint]]").unwrap_or(&kept);
        std::fs::write(&path, kept).unwrap();
        Experiment::load(&path).unwrap()
    }

    #[test]
    fn with_the_arm_and_the_hand_eye_exact_the_consensus_truth_is_the_registered_truth() {
        // Every view is displaced by the registration alone: D_i = identity.
        let dir = tempfile::tempdir().unwrap();
        let experiment = quickstart(
            dir.path(),
            "[range]\nsigma0 = 0.001\nk = 0.0\nangular_sigma = 0.0\ndropout = 0.0\n\
             [world_from_scene]\nsigma = [0.004, 0.004, 0.004, 0.02, 0.02, 0.02]\n",
            6,
        );
        let run = simulate(&experiment, 2, |_| {}).unwrap();
        for d in view_displacements(&run.scans, &run.truth) {
            assert!(d.translation.vector.norm() < 1e-12, "{d:?}");
            assert!(d.rotation.angle() < 1e-12, "{d:?}");
        }
        let offset = experiment.map_offset(2);
        let ours = consensus_truth(&experiment, &run.scans, &run.truth, &offset, &KeyBox::ALL);
        let registered = registered_truth(&experiment, &run.truth, 0.01, &offset, &KeyBox::ALL);
        assert_eq!(ours.leaves(), registered.leaves());
    }

    #[test]
    fn the_consensus_truth_holds_the_surface_where_a_lone_view_puts_it() {
        // One viewpoint with a large hand-eye error (registration and arm
        // exact): the view's displacement is the mean, so every true hit seen
        // through the nominal chain lies on the consensus truth's surface, and some
        // off the registered truth's (here the truth itself).
        let dir = tempfile::tempdir().unwrap();
        let experiment = quickstart(
            dir.path(),
            "[range]\nsigma0 = 0.001\nk = 0.0\nangular_sigma = 0.0\ndropout = 0.0\n\
             [robot_from_camera]\nsigma = [0.01, 0.01, 0.01, 0.05, 0.05, 0.05]\n",
            1,
        );
        assert_eq!(experiment.viewpoints().len(), 1);
        let seed = 3;
        let run = simulate(&experiment, seed, |_| {}).unwrap();
        let offset = experiment.map_offset(seed);
        let ours = consensus_truth(&experiment, &run.scans, &run.truth, &offset, &KeyBox::ALL);
        let registered = registered_truth(&experiment, &run.truth, 0.01, &offset, &KeyBox::ALL);
        let (hits, in_ours, in_registered) =
            hits_placed_by_the_nominal_chain(&experiment, &run, &offset, (&ours, &registered));
        assert!(hits > 5_000, "{hits} hits");
        assert_eq!(in_ours, hits, "every hit on the consensus truth's surface");
        // The hits that move into the table's slab stay occupied there.
        assert!(
            (in_registered as f64) < 0.97 * hits as f64,
            "the hand-eye error moves hits off the registered truth: {in_registered} of {hits}"
        );
    }

    #[test]
    fn the_mean_displacement_averages_translations_and_rotation_vectors() {
        let a = Isometry3::new(Vector3::new(0.002, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.01));
        let b = Isometry3::new(
            Vector3::new(0.0, 0.004, 0.0),
            Vector3::new(0.0, 0.0, -0.004),
        );
        let mean = mean_displacement(&[a, b]);
        assert!((mean.translation.vector - Vector3::new(0.001, 0.002, 0.0)).norm() < 1e-15);
        assert!((mean.rotation.scaled_axis() - Vector3::new(0.0, 0.0, 0.003)).norm() < 1e-12);
        assert_eq!(mean_displacement(&[]), Isometry3::identity());
    }
}
