//! `sigmap score`: any OctoMap file scored as `sigmap run` scores its maps
//! (`experiment::run::scoring::score_external`), or against a known scene with
//! the mask of recorded scans (`experiment::run::scoring::score_against_scene`).

use super::{with_threads, ScoreArgs};
use crate::error::{Error, Result};
use crate::experiment::output::wrong_cells::{write_wrong_cells, ErrorsFormat};
use crate::experiment::run::placement::{
    Placement, Refinement, SurfaceAgreement, AGREEMENT_WARNING,
};
use crate::experiment::run::recorded::read_scans;
use crate::experiment::run::runner::append_row;
use crate::experiment::run::scoring::{score_against_scene, score_external, Scored};
use crate::experiment::study::metrics::{Kind, RunRow, METRICS};
use crate::experiment::Experiment;
use crate::geometry::Pose;
use crate::mapping::octomap_io::read_octree;
use crate::mapping::octree::Clamp;
use crate::mapping::Octree;
use crate::sim::scene::Scene;

/// `sigmap score`.
pub(crate) fn run(args: ScoreArgs) -> Result<()> {
    check_roles(&args)?;
    if args.errors.is_some() && args.errors == args.csv {
        return Err(Error::Usage(
            "--errors and --csv name the same file: the list would replace the rows".into(),
        ));
    }
    let errors = args.errors.as_deref().map(ErrorsFormat::of).transpose()?;
    let list_wrong = errors.is_some();
    let name = crate::files::stem(&args.map);
    let (scored, map, against) = match (&args.scene, &args.experiment) {
        (Some(scene), _) => against_scene(&args, scene, &name, list_wrong)?,
        (None, Some(path)) => {
            let experiment =
                Experiment::load_cell_index(path, args.cell).map_err(super::cell_flag)?;
            super::print_notes(experiment.notes(), args.run.quiet);
            let seed = args.run.seed.unwrap_or(experiment.seed());
            let map = read_octree(&args.map, experiment.map().clamp())
                .map_err(|e| e.context("the map (first argument): "))?;
            let scored = with_threads(args.run.threads, || {
                score_external(&experiment, seed, &map, &name, list_wrong)
            })??;
            let cell = match Experiment::cell_label(experiment.cell()) {
                label if label.is_empty() => String::new(),
                label => format!(", cell {label}"),
            };
            (
                scored,
                map,
                format!("experiment '{}', seed {seed}{cell}", experiment.name()),
            )
        }
        (None, None) => {
            return Err(Error::Usage(
                "give the experiment file, or --scene SCENE.toml --scans SCANS.graph".into(),
            ))
        }
    };
    let Scored { row, wrong } = scored;
    if let Some(path) = &args.csv {
        append_row(path, &row).map_err(|e| e.hint("choose another --csv file"))?;
    }
    if let (Some(path), Some(format)) = (&args.errors, errors) {
        write_wrong_cells(path, format, &map, &wrong)?;
    }
    if !args.run.quiet {
        print_row(&format!("{} against {against}:", args.map.display()), &row);
        if args
            .map
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("bt"))
        {
            eprintln!("{BT_NOTE}");
        }
        if let Some(path) = &args.errors {
            eprintln!(
                "wrote {}: the {} scored cells the map calls wrongly",
                path.display(),
                wrong.len()
            );
        }
    }
    Ok(())
}

/// Why a `.bt` scores otherwise than the `.ot` of the same tree.
const BT_NOTE: &str = "note: a .bt holds only occupied and free (OctoMap's log-odds >= 0 \
    rule), so the cells these scores call unknown (|log-odds| < 0.1) are classified, and \
    Brier, log-loss and ROC AUC see hard 0/1 maps; score the .ot (graph2tree writes \
    NAME.bt.ot beside NAME.bt) for the scores sigmap run gives its own maps";

/// Refuses arguments in each other's places: the map (an OctoMap `.bt` or
/// `.ot`) comes first, the experiment (`.toml`) second.
fn check_roles(args: &ScoreArgs) -> Result<()> {
    if args
        .map
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
    {
        return Err(Error::Usage(format!(
            "{} is an experiment file where the map goes: the map (.bt or .ot) comes first, \
             `sigmap score MAP EXPERIMENT`",
            args.map.display()
        )));
    }
    Ok(())
}

/// The row of the map against `scene` with the mask of `--scans`.
fn against_scene(
    args: &ScoreArgs,
    scene: &std::path::Path,
    name: &str,
    list_wrong: bool,
) -> Result<(Scored, Octree, String)> {
    if args.run.seed.is_some() {
        return Err(Error::Usage(
            "--seed does not apply with --scene: recorded scans have no seed".into(),
        ));
    }
    if let Some(reach) = args.max_range {
        if !(reach.is_finite() && reach > 0.0) {
            return Err(Error::Usage(format!(
                "--max-range {reach}: give a positive distance in metres"
            )));
        }
    }
    let scene_data = Scene::load(scene)?;
    super::print_notes(scene_data.notes(), args.run.quiet);
    let scans = args.scans.as_ref().ok_or_else(|| {
        Error::Usage("--scene needs --scans SCANS.graph, the scans the map was built from".into())
    })?;
    let (nodes, notes) = read_scans(scans, &args.depth.options())?;
    super::print_notes(&notes, args.run.quiet);
    // OctoMap's clamp, as a map file written by OctoMap or sigmap keeps it.
    let map = read_octree(&args.map, Clamp::OCTOMAP)
        .map_err(|e| e.context("the map (first argument): "))?;
    let map_from_scene =
        Pose::from_params(&args.scene_pose.unwrap_or([0.0; 6]).into()).to_isometry();
    let scored = with_threads(args.run.threads, || {
        score_against_scene(
            &map,
            &scene_data,
            &map_from_scene,
            &nodes,
            args.max_range,
            name,
            list_wrong,
        )
    })??;
    let placement = Placement::new(
        &scene_data,
        &nodes,
        args.max_range,
        AGREEMENT_CELLS * map.resolution(),
    );
    let agreement = placement.agreement(&map_from_scene);
    if agreement.share() < AGREEMENT_WARNING {
        super::print_notes(&[misplaced_scene(&agreement, scene)], args.run.quiet);
    }
    let refined = placement.refine(&map_from_scene);
    if let Some(refined) = refined.filter(|r| {
        r.largest_move > 0.5 * map.resolution() && r.agreement.share() >= agreement.share()
    }) {
        let pose = Pose::from_isometry(&(refined.correction * map_from_scene));
        super::print_notes(&[moved_scene(&refined, &agreement, &pose)], args.run.quiet);
    }
    Ok((
        scored,
        map,
        format!(
            "scene {} seen by {} ({:.1}% of {} returns meet it within {} m of their range)",
            scene.display(),
            scans.display(),
            100.0 * agreement.share(),
            agreement.sampled,
            agreement.tolerance,
        ),
    ))
}

/// How near its range, in cells, a return's ray must meet the scene.
const AGREEMENT_CELLS: f64 = 2.0;

/// The warning for scans whose rays mostly meet the scene elsewhere than at
/// their returns.
fn misplaced_scene(agreement: &SurfaceAgreement, scene: &std::path::Path) -> String {
    format!(
        "warning: only {:.0}% of the scans' returns ({} of the {} looked at) meet the \
         scene's first surface along their ray within {} m ({AGREEMENT_CELLS} cells) of \
         their range, with {} where --scene-pose puts it: check \
         --scene-pose (the scene's pose in the map frame, x,y,z,roll,pitch,yaw), the scene's \
         units and frame, and that it models what the scans see; the scores count every \
         return off the model against the map",
        100.0 * agreement.share(),
        agreement.near,
        agreement.sampled,
        agreement.tolerance,
        scene.display()
    )
}

/// The note for scans that fit the scene better moved: the move, how many
/// degrees of freedom the returns fix, and the `--scene-pose` that makes it.
fn moved_scene(refined: &Refinement, agreement: &SurfaceAgreement, pose: &Pose) -> String {
    // Four decimals, a value that rounds to zero printed as 0.0000.
    let fixed = |v: f64| format!("{:.4}", if v.abs() < 5e-5 { 0.0 } else { v });
    let s = refined.centroid_shift.map(fixed);
    let turn = refined.correction.rotation.angle().to_degrees();
    let free = match refined.fixed {
        6 => String::new(),
        fixed => format!(
            "; the returns fix {fixed} of the 6 degrees of freedom and leave {} free, and the \
             scene is not moved along those",
            free_moves(&refined.freedom)
        ),
    };
    let pose = pose.params().iter().map(|&v| fixed(v)).collect::<Vec<_>>();
    format!(
        "note: the scans' returns fit the scene better moved by ({}, {}, {}) m at \
         their centroid and turned by {turn:.2} degrees about it, in the map frame (no return \
         moves more than {:.4} m; {:.1}% of the returns meet it within {} m of their range, \
         against {:.1}% where it stands{free}): to score against it there, give \
         --scene-pose {}",
        s.x,
        s.y,
        s.z,
        refined.largest_move,
        100.0 * refined.agreement.share(),
        refined.agreement.tolerance,
        100.0 * agreement.share(),
        pose.join(",")
    )
}

/// The moves the returns leave free, named from [`Refinement::freedom`]:
/// the axes wholly free ("x, y and the turn about z"), else the axes the
/// free moves mix.
fn free_moves(freedom: &[f64; 6]) -> String {
    const MOVES: [&str; 6] = [
        "x",
        "y",
        "z",
        "the turn about x",
        "the turn about y",
        "the turn about z",
    ];
    let named = |least: f64| -> Vec<&str> {
        MOVES
            .iter()
            .zip(freedom)
            .filter(|(_, &share)| share > least)
            .map(|(name, _)| *name)
            .collect()
    };
    let list = |names: Vec<&str>| match names.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => String::new(),
    };
    if freedom.iter().all(|&share| !(0.1..=0.9).contains(&share)) {
        list(named(0.9))
    } else {
        match freedom.iter().sum::<f64>().round() {
            count if count < 1.5 => format!("a mix of {}", list(named(0.1))),
            count => format!("{count} mixes of {}", list(named(0.1))),
        }
    }
}

fn print_row(title: &str, row: &RunRow) {
    println!("{title}");
    for (metric, value) in METRICS.iter().zip(&row.values) {
        if value.is_nan() {
            continue;
        }
        match metric.kind {
            Kind::Count => println!("  {:<24} {value:>12}", metric.name),
            Kind::Real => println!("  {:<24} {value:>12.6}", metric.name),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::free_moves;

    #[test]
    fn free_moves_are_named_by_axis_or_as_mixes() {
        assert_eq!(
            free_moves(&[1.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            "x, y and the turn about z"
        );
        assert_eq!(free_moves(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), "z");
        // One free move along x + y, one along the turn about y and z.
        let half = [0.5, 0.5, 0.0, 0.0, 0.0, 0.0];
        assert_eq!(free_moves(&half), "a mix of x and y");
        let two = [0.5, 0.5, 0.02, 0.0, 0.98, 0.0];
        assert_eq!(free_moves(&two), "2 mixes of x, y and the turn about y");
    }
}
