use super::*;
use crate::experiment::output::export::scan_nodes;
use crate::experiment::run::runner::quickstart_with_profile;
use crate::experiment::{simulate, Experiment};
use crate::geometry::{Point3, Vector3};
use crate::sim::scene::Scene;
use std::path::Path;

/// The quickstart with an exact arm, hand-eye and registration and a
/// noise-free sensor that drops nothing: its believed scans are the true
/// ones, and its returns lie on the scene.
fn exact_quickstart(dir: &Path) -> Experiment {
    let exact = "[range]\nsigma0 = 0.0\nk = 0.0\nangular_sigma = 0.0\ndropout = 0.0\n";
    quickstart_with_profile(dir, exact, "")
}

/// The exact quickstart's scans of seed 3 as recorded nodes, with the
/// scene's pose in their map frame, the maximum range and a tolerance of
/// two cells.
struct ExactScans {
    experiment: Experiment,
    nodes: Vec<ScanNode>,
    placed: Isometry3,
    max_range: Option<f64>,
    tolerance: f64,
}

impl ExactScans {
    /// The scans' returns against the quickstart's scene.
    fn placement(&self) -> Placement<'_> {
        let scene = self.experiment.scene();
        Placement::new(scene, &self.nodes, self.max_range, self.tolerance)
    }
}

fn exact_scans(dir: &Path) -> ExactScans {
    let experiment = exact_quickstart(dir);
    let seed = 3;
    let run = simulate(&experiment, seed, |_| {}).unwrap();
    let offset = experiment.map_offset(seed);
    let nodes = scan_nodes(&experiment.mapper_view(), &run.scans, &offset);
    ExactScans {
        nodes,
        placed: Isometry3::translation(offset.x, offset.y, offset.z),
        max_range: Some(experiment.scanner().max_range),
        tolerance: 2.0 * experiment.resolution(),
        experiment,
    }
}

#[test]
fn returns_agree_with_the_scene_where_it_stands_and_not_where_it_is_misplaced() {
    // The exact quickstart's returns are where its rays first meet the
    // scene: every ray cast on the scene in place meets it at its range. The
    // scene raised 3 cm (three cells) stands in the rays' way before the
    // table top's returns, and the share falls below the warning.
    let dir = tempfile::tempdir().unwrap();
    let scans = exact_scans(dir.path());
    let placed = scans.placed;
    let here = scans.placement().agreement(&placed);
    assert!(here.sampled > 5_000, "{here:?}");
    assert!(here.share() > 0.99, "{here:?}");
    let raised = scans
        .placement()
        .agreement(&(Isometry3::translation(0.0, 0.0, 0.03) * placed));
    assert_eq!(raised.sampled, here.sampled);
    assert!(raised.share() < AGREEMENT_WARNING - 0.2, "{raised:?}");
}

#[test]
fn a_misplaced_scene_is_moved_back_onto_the_returns() {
    // The exact quickstart's scene moved 2 cm, −1.5 cm and 3 cm in the map
    // frame: the refinement moves it back along every direction its returns
    // fix (the table top, the objects' sides: all three here), to well
    // inside a cell, and the returns agree with it again.
    let dir = tempfile::tempdir().unwrap();
    let scans = exact_scans(dir.path());
    let (placed, cell) = (scans.placed, scans.experiment.resolution());
    let misplacement = Vector3::new(0.02, -0.015, 0.03);
    let misplaced = nalgebra::Translation3::from(misplacement) * placed;
    let before = scans.placement().agreement(&misplaced);
    let refined = scans.placement().refine(&misplaced).unwrap();
    assert!(before.share() < 0.5, "{before:?}");
    assert_eq!(refined.fixed, 3, "{refined:?}");
    let left = refined.shift + misplacement;
    assert!(left.norm() < 0.1 * cell, "{refined:?}: {left}");
    assert!(refined.agreement.share() > 0.99, "{refined:?}");
    // In place, it stays.
    let stays = scans.placement().refine(&placed).unwrap();
    assert!(stays.shift.norm() < 1e-3 * cell, "{stays:?}");
}

#[test]
fn a_lone_plane_fixes_only_the_direction_across_it() {
    // A floor seen from above: its returns fix the scene's height, not
    // where it lies along the floor. Moved 3 cm, 2 cm and 1 cm, it comes
    // back 1 cm down and is left where it is sideways.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("floor.toml");
    std::fs::write(
        &path,
        "[workspace]\nmin = [-2, -2, -1]\nmax = [2, 2, 1]\n\
         [[object]]\nname = \"floor\"\nshape = \"box\"\nsize = [3, 3, 0.1]\nxyz = [0, 0, -0.05]\n",
    )
    .unwrap();
    let scene = Scene::load(&path).unwrap();
    // One node 1 m up looking down (sensor z along the map's −z).
    let down = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let node = ScanNode {
        id: 0,
        map_from_sensor: Isometry3::from_parts(nalgebra::Translation3::new(0.0, 0.0, 1.0), down),
        points: (0..400)
            .map(|k| {
                let (u, v) = (
                    f64::from(k % 20) / 20.0 - 0.5,
                    f64::from(k / 20) / 20.0 - 0.5,
                );
                Point3::new(u, v, 1.0)
            })
            .collect(),
    };
    let nodes = [node];
    let tolerance = 0.02;
    let misplaced = Isometry3::translation(0.03, 0.02, 0.01);
    let refined = Placement::new(&scene, &nodes, None, tolerance)
        .refine(&misplaced)
        .unwrap();
    assert_eq!(refined.fixed, 1, "{refined:?}");
    let expected = Vector3::new(0.0, 0.0, -0.01);
    assert!((refined.shift - expected).norm() < 1e-6, "{refined:?}");
    assert!(refined.agreement.share() == 1.0, "{refined:?}");
}
