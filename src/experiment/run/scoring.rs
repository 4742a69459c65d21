//! Scoring maps built elsewhere (`sigmap score`): against the run of an
//! experiment, exactly as `sigmap run` scores its own maps, or against a
//! known scene with the observable mask of recorded scans — the path for
//! real scans of a workcell whose CAD model is known.

use crate::error::{Error, Result};
use crate::eval::ground_truth::{voxelise_within, KeyBox};
use crate::eval::observable::{check_mask_cost, observable_along, SeenRay};
use crate::eval::scores::{score_map, wrong_cells, WrongCell};
use crate::experiment::run::runner::{observable, run_truth};
use crate::experiment::study::metrics::{Measured, RunRow};
use crate::experiment::{simulate, Experiment};
use crate::geometry::{Isometry3, Point3};
use crate::mapping::scan_graph::ScanNode;
use crate::mapping::Octree;
use crate::sim::scene::Scene;

/// Whose row a score is: the sweep cell, the seed and the method's name;
/// and whether the cells the map calls wrongly are listed too.
struct RowOf<'a> {
    cell: String,
    seed: u64,
    name: &'a str,
    list_wrong: bool,
}

/// A map scored: its runs.csv row, and (when asked for) the scored cells it
/// calls wrongly ([`wrong_cells`]).
#[derive(Clone, Debug)]
pub struct Scored {
    /// The row.
    pub row: RunRow,
    /// The false-free and false-occupied cells, in Morton order (empty
    /// unless asked for).
    pub wrong: Vec<WrongCell>,
}

/// The row of `map` scored against `truth` over `observable`.
fn row_of(
    map: &Octree,
    truth: &Octree,
    observable: &rustc_hash::FxHashSet<u64>,
    whose: RowOf,
) -> Scored {
    let scores = score_map(map, truth, observable);
    let stats = map.stats();
    let measured = Measured {
        scores: &scores,
        consistency: None,
        nees_point: f64::NAN,
        stats: &stats,
    };
    let wrong = if whose.list_wrong {
        wrong_cells(map, truth, observable)
    } else {
        Vec::new()
    };
    Scored {
        row: RunRow::new(
            whose.cell,
            whose.seed,
            whose.name,
            map.resolution(),
            &measured,
        ),
        wrong,
    }
}

/// Refuses a map whose resolution is not `wanted`, saying what to do.
fn check_map_resolution(map: &Octree, wanted: f64, what: &str) -> Result<()> {
    if (map.resolution() - wanted).abs() > 1e-9 * wanted {
        return Err(Error::Usage(format!(
            "the map's resolution is {} m, {what} {wanted} m: build the map at {wanted} m \
             (graph2tree -res, sigmap map --resolution)",
            map.resolution()
        )));
    }
    Ok(())
}

/// Scores a map built elsewhere (any OctoMap file) against the run of
/// `experiment` with `seed`, with the ground truth and observable mask
/// `sigmap run` uses, as a runs.csv row whose method is `name`. The map must
/// be in the run's map frame (the scene frame shifted by
/// `Experiment::map_offset`, which `sigmap export` applies) at the
/// experiment's resolution; another resolution is refused.
/// With `list_wrong`, the cells it calls wrongly are listed too.
pub fn score_external(
    experiment: &Experiment,
    seed: u64,
    map: &Octree,
    name: &str,
    list_wrong: bool,
) -> Result<Scored> {
    check_map_resolution(map, experiment.resolution(), "the experiment's")?;
    experiment.check_truth_cost()?;
    let run = simulate(experiment, seed, |_| {})?;
    let offset = experiment.map_offset(seed);
    let observable = observable(experiment, &run.truth.scans, &offset);
    let truth = run_truth(
        experiment,
        seed,
        &KeyBox::spanning(observable.iter().copied()),
    );
    let cell = Experiment::cell_label(experiment.cell());
    let whose = RowOf {
        cell,
        seed,
        name,
        list_wrong,
    };
    let mut scored = row_of(map, &truth, &observable, whose);
    scored.row.resolution = experiment.resolution();
    Ok(scored)
}

/// The rays of recorded scans as the observable mask takes them: from each
/// node's origin to each of its points in the map frame; a point farther
/// than `max_range` from its origin is a beam that returned nothing, cut at
/// `max_range` with no surface seen (as `graph2tree -m` and
/// `sigmap export`'s no-return points have it); without `max_range` every
/// point is a hit.
pub fn recorded_rays(
    nodes: &[ScanNode],
    max_range: Option<f64>,
) -> impl Iterator<Item = SeenRay> + '_ {
    nodes.iter().flat_map(move |node| {
        let origin = Point3::from(node.map_from_sensor.translation.vector);
        node.points.iter().map(move |p| {
            let end = node.map_from_sensor * p;
            let length = p.coords.norm();
            match max_range {
                Some(reach) if length > reach => SeenRay {
                    origin,
                    end: origin + (end - origin) * (reach / length),
                    hit: false,
                },
                _ => SeenRay {
                    origin,
                    end,
                    hit: true,
                },
            }
        })
    })
}

/// Scores a map of recorded scans against a known scene: the ground truth is
/// the scene's solids placed in the map frame by `map_from_scene` at the
/// map's resolution, the observable mask the cells the recorded rays
/// crossed or ended in ([`recorded_rays`]). Returns the row (method `name`,
/// seed 0, no cell).
pub fn score_against_scene(
    map: &Octree,
    scene: &Scene,
    map_from_scene: &Isometry3,
    nodes: &[ScanNode],
    max_range: Option<f64>,
    name: &str,
    list_wrong: bool,
) -> Result<Scored> {
    scene.check_resolution(map.resolution())?;
    let steps: f64 = recorded_rays(nodes, max_range)
        .map(|ray| (ray.end - ray.origin).norm() / map.resolution())
        .sum();
    check_mask_cost(
        steps,
        steps,
        map.resolution(),
        "the recorded rays (--scans)",
    )
    .map_err(Error::Usage)?;
    let observable = observable_along(recorded_rays(nodes, max_range), map.resolution());
    let region = KeyBox::spanning(observable.iter().copied());
    let truth = voxelise_within(scene, map.resolution(), map_from_scene, &region);
    let whose = RowOf {
        cell: String::new(),
        seed: 0,
        name,
        list_wrong,
    };
    let scored = row_of(map, &truth, &observable, whose);
    if scored.row.get("observable_cells") == 0.0 {
        // Every score would be 0/0: the rays and the scene do not meet.
        let message = if observable.is_empty() {
            "the recorded rays cross no cell (are they cut at a --max-range shorter than a \
             cell?): nothing to score"
                .to_string()
        } else {
            let cut = max_range.map_or(String::new(), |m| format!(" (cut at --max-range {m})"));
            format!(
                "none of the {} cells the recorded rays cross{cut} lies in the scene's \
                 workspace where --scene-pose puts it (default: at the map frame's origin): \
                 nothing to score; check the scene's pose in the map frame and that the scans \
                 are in it",
                observable.len()
            )
        };
        return Err(Error::input(&scene.source, message));
    }
    Ok(scored)
}

#[cfg(test)]
mod tests;
