use super::*;
use crate::experiment::output::export::scan_nodes;
use crate::experiment::run::runner::{quickstart_with_profile, run_seed};
use crate::experiment::RunMethod;
use crate::geometry::Vector3;
use crate::mapping::Method;
use std::path::Path;

/// The quickstart with an exact arm, hand-eye and registration and a
/// noise-free sensor that drops nothing, `grid_offset` on: its
/// believed scans are the true ones.
fn exact_quickstart(dir: &Path) -> Experiment {
    let exact = "[range]\nsigma0 = 0.0\nk = 0.0\nangular_sigma = 0.0\ndropout = 0.0\n";
    let experiment = quickstart_with_profile(dir, exact, "");
    assert!(experiment.grid_offset());
    experiment
}

#[test]
fn an_exact_run_scored_against_its_scene_and_scans_gives_the_run_row() {
    // At zero pose error the exported graph's rays are the true rays, so the
    // scene's solids at the run's grid offset and the graph's mask give the
    // row `sigmap run` gives, metric for metric.
    let dir = tempfile::tempdir().unwrap();
    let experiment = exact_quickstart(dir.path());
    let seed = 2;
    let outcome = run_seed(&experiment, seed).unwrap();
    let (rows, maps) = (outcome.rows, outcome.maps);
    let run = simulate(&experiment, seed, |_| {}).unwrap();
    let offset = experiment.map_offset(seed);
    assert!(offset.norm() > 0.0);
    let view = experiment.mapper_view();
    let nodes = scan_nodes(&view, &run.scans, &offset);
    let map_from_scene = Isometry3::translation(offset.x, offset.y, offset.z);
    for ((method, map), run_row) in experiment.methods().iter().zip(&maps).zip(&rows) {
        let row = score_against_scene(
            map,
            experiment.scene(),
            &map_from_scene,
            &nodes,
            Some(experiment.scanner().max_range),
            method.as_str(),
            false,
        )
        .unwrap()
        .row;
        for name in [
            "observable_cells",
            "occupied_cells",
            "precision",
            "recall",
            "f1",
        ] {
            assert_eq!(row.get(name), run_row.get(name), "{method} {name}");
        }
        for (metric, (a, b)) in crate::experiment::study::metrics::METRICS
            .iter()
            .zip(row.values.iter().zip(&run_row.values))
        {
            // The consistency metrics are the run's own (no scans' truth here).
            if metric.name.contains("nees") || metric.name.starts_with("coverage") {
                continue;
            }
            assert!(
                a == b || (a.is_nan() && b.is_nan()),
                "{method} {}: {a} vs {b}",
                metric.name
            );
        }
    }
    // A wrong scene pose moves the truth: the scores change.
    let moved = map_from_scene * Isometry3::translation(0.03, 0.0, 0.0);
    let ray_update = experiment
        .methods()
        .iter()
        .position(|m| *m == RunMethod::Own(Method::RayUpdate))
        .unwrap();
    let row = score_against_scene(
        &maps[ray_update],
        experiment.scene(),
        &moved,
        &nodes,
        Some(experiment.scanner().max_range),
        "ray_update",
        false,
    )
    .unwrap()
    .row;
    assert!(
        row.get("f1") < rows[ray_update].get("f1") - 0.1,
        "{} vs {}",
        row.get("f1"),
        rows[ray_update].get("f1")
    );
}

#[test]
fn recorded_points_beyond_the_maximum_range_are_rays_that_saw_nothing() {
    let node = ScanNode {
        pixels: None,
        id: 0,
        map_from_sensor: Isometry3::translation(1.0, 0.0, 0.0),
        points: vec![Point3::new(0.0, 0.0, 0.5), Point3::new(0.0, 0.0, 4.0)],
    };
    let rays: Vec<SeenRay> = recorded_rays(std::slice::from_ref(&node), Some(2.0)).collect();
    assert_eq!(rays[0].end, Point3::new(1.0, 0.0, 0.5));
    assert!(rays[0].hit);
    assert!((rays[1].end.coords - Vector3::new(1.0, 0.0, 2.0)).norm() < 1e-12);
    assert!(!rays[1].hit);
    let rays: Vec<SeenRay> = recorded_rays(std::slice::from_ref(&node), None).collect();
    assert!(rays.iter().all(|r| r.hit));
    assert_eq!(rays[1].end, Point3::new(1.0, 0.0, 4.0));
}
