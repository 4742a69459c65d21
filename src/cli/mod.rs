//! The `sigmap` command line: one clap adapter per command, each in its own
//! file (`run.rs` also holds `merge`, `cluster.rs` `submit` and `status`).
//! An adapter parses arguments, calls the library (`experiment`, `mapping`,
//! `eval`, `uncertainty`), draws the progress bar and prints; it holds no
//! logic of its own. Exit codes: 0 ok, 1 a failed check, 2 bad input or
//! usage (`error`).

mod cluster;
mod export;
mod ground_truth;
mod map;
mod opdf;
mod parse;
mod propagate;
mod regress;
mod run;
mod score;
mod simulate;

use crate::error::{Error, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use parse::{
    method_parser, parse_point, parse_pose, parse_shard, parse_tasks, pooling_parser, risk_parser,
};
pub(crate) use parse::{resolution_arg, RiskArg};
use std::io::IsTerminal;
use std::path::PathBuf;

/// Simulation-backed evaluation of uncertainty-aware occupancy maps.
#[derive(Parser, Debug)]
#[command(name = "sigmap", version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run an experiment and score every method against the ground truth
    ///
    /// Every seed (in parallel), every method on each seed's scans, scored
    /// against the ground truth; writes runs.csv, summary.csv, timings.csv and
    /// the first seed's maps. Finished runs are kept: a re-run skips them
    /// (--fresh redoes everything).
    Run(RunArgs),
    /// Simulate an experiment's scans and write them (CSV, PLY, chains)
    ///
    /// Ray-cast every viewpoint from the true (error-drawn) sensor pose and
    /// write what the modeller receives (CSV, PLY, nominal chains with
    /// covariances) and, apart, the truth.
    Simulate(SimulateArgs),
    /// Export one run's scans for another mapper (OctoMap ScanGraph, PLY, TUM poses)
    ///
    /// Writes scans.graph (graph2tree, octovis), one PLY per viewpoint, the
    /// nominal poses as a TUM trajectory and a README naming the frames; the
    /// believed poses only, never the truth. Prints the graph2tree command.
    Export(ExportArgs),
    /// Score any OctoMap file against the ground truth of an experiment's run
    ///
    /// The same ground truth, observable mask and metrics as `sigmap run`, for
    /// a map built by another mapper (e.g. graph2tree on `sigmap export`'s
    /// scans). Prints the scores; --csv appends the row to a runs.csv-like file.
    Score(ScoreArgs),
    /// Propagate one measurement through an uncertain chain with every method
    ///
    /// Blind, Jacobian, unscented and Monte Carlo: prints each method's
    /// scene-frame mean, 3x3 covariance and cost; or, with --sweep, reproduces
    /// the paper's comparison over rotation sigmas (CSV + SVG).
    Propagate(PropagateArgs),
    /// Draw the occupancy profile along a beam (the paper's figures 1 and 6)
    ///
    /// For several range and origin sigmas, as SVG, with the curves as CSV.
    Opdf(OpdfArgs),
    /// Build one run's occupancy map with one method, as an OctoMap file
    ///
    /// blind, jacobian, unscented: the paper's OPDF merge; correlated: the
    /// unscented merge with the shared pose errors accounted once;
    /// ray_update: OctoMap's update (ray_update_discrete: its discretized
    /// insertion). Writes a .bt or .ot file. With --scans
    /// and --profile, maps scans recorded elsewhere (an OctoMap ScanGraph or
    /// the plain-text log log2graph reads) instead of an experiment's
    /// simulated run.
    Map(MapArgs),
    /// Write a scene's true occupancy as an OctoMap file
    ///
    /// A cell is occupied when its box meets a solid, surface or interior.
    GroundTruth(GroundTruthArgs),
    /// Join the folders of `sigmap run --shard i/n` into the usual files
    ///
    /// Checks that every shard ran the same experiment inputs and sigmap
    /// version, and that no run is missing; the merged runs.csv and
    /// summary.csv are byte-identical to a one-machine run.
    Merge(MergeArgs),
    /// Submit an experiment to SLURM as a job array of shards plus a merge
    ///
    /// Writes the sbatch scripts into the results folder (readable, to adapt),
    /// submits N tasks where task k runs `sigmap run ... --shard k/N`, and a
    /// merge job that waits for them (afterok). --resume submits only the
    /// shards that still miss runs.
    Submit(SubmitArgs),
    /// Say which runs of a submitted experiment are done, missing or failed
    Status(StatusArgs),
    /// Compare a summary.csv with a baseline, or check a method's
    /// consistency; exit 1 on a regression or an inconsistent method
    ///
    /// Prints a table of the metrics whose mean drifted past its tolerance,
    /// and a verdict per cell for each method checked.
    Regress(RegressArgs),
}

#[derive(Args, Debug)]
pub(crate) struct SubmitArgs {
    /// The experiment file (TOML).
    experiment: PathBuf,
    /// Number of array tasks (shards), 1 to 10000.
    #[arg(long, default_value_t = 1, value_parser = parse_tasks)]
    tasks: usize,
    /// Results folder on the shared filesystem [default: results/<experiment>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// An extra argument for sbatch (partition, time, memory...), repeatable:
    /// --sbatch-arg=--partition=short --sbatch-arg=--time=01:00:00.
    #[arg(long, allow_hyphen_values = true)]
    sbatch_arg: Vec<String>,
    /// Submit only the shards with missing runs (and the merge).
    #[arg(long)]
    resume: bool,
}

#[derive(Args, Debug)]
pub(crate) struct StatusArgs {
    /// The results folder of a submission.
    dir: PathBuf,
}

#[derive(Args, Debug)]
pub(crate) struct MergeArgs {
    /// The experiment file the shards ran.
    experiment: PathBuf,
    /// The shards' output folders.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// Output folder [default: results/<experiment>].
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub(crate) struct RegressArgs {
    /// The current summary.csv.
    current: PathBuf,
    /// The baseline summary.csv (this, `--consistent`, or both).
    #[arg(long)]
    baseline: Option<PathBuf>,
    /// Override a metric's tolerance: METRIC=VALUE (absolute), repeatable.
    /// Defaults: 0.01 for scores in [0, 1]; 5% of the baseline for anees and log_loss.
    #[arg(long)]
    tolerance: Vec<String>,
    /// Fail unless METHOD's covariances are consistent in every cell: its
    /// mean NEES of one point a run within the 95% band honest covariances
    /// give it; repeatable.
    #[arg(long, value_name = "METHOD")]
    consistent: Vec<String>,
}

#[derive(Args, Debug)]
pub(crate) struct GroundTruthArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Finest voxel edge (m).
    #[arg(long, default_value_t = 0.01)]
    resolution: f64,
    /// Output file, .bt or .ot.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args, Debug)]
pub(crate) struct MapArgs {
    /// The experiment file (TOML); or give recorded scans with --scans.
    #[arg(required_unless_present = "scans")]
    experiment: Option<PathBuf>,
    /// blind, jacobian, unscented, correlated, ray_update or
    /// ray_update_discrete (OctoMap's insertion with discretize = true); or
    /// registered_truth (the truth as the run's scene registration places
    /// it) or consensus_truth (as its scans together place it; neither for
    /// --scans).
    #[arg(long, default_value = "unscented", value_parser = method_parser())]
    method: crate::mapping::Method,
    /// Finest voxel edge (m) [default: the experiment's `resolution`; with
    /// --scans 0.1, as graph2tree].
    #[arg(long, allow_negative_numbers = true)]
    resolution: Option<f64>,
    /// Sweep cell (0-based, in the order of summary.csv) [default: the base
    /// experiment]: with --seed, the map `sigmap run` builds for that cell
    /// and seed.
    #[arg(long, conflicts_with = "scans")]
    cell: Option<usize>,
    /// Map file, .bt or .ot [default: results/<experiment>/map_<method>.bt;
    /// required with --scans].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write the rays (origins and end points) for OctoMap's benchmark:
    /// the rays the ray update inserts (with beam pooling, the pooled points).
    #[arg(long, conflicts_with = "scans")]
    export_rays: Option<PathBuf>,
    /// Map scans recorded elsewhere: an OctoMap ScanGraph (.graph, e.g. from
    /// log2graph or `sigmap export`), the plain-text log log2graph reads
    /// (`NODE x y z roll pitch yaw` lines, each followed by `x y z` lines),
    /// points in each node's sensor frame, or a folder of depth images in
    /// the TUM RGB-D layout (depth.txt, groundtruth.txt, depth/*.png).
    #[arg(long, conflicts_with = "experiment", requires = "profile")]
    scans: Option<PathBuf>,
    /// With --scans: the error profile (TOML) the scans are believed with;
    /// its [world_from_robot] is the error of each node's pose.
    #[arg(long, requires = "scans")]
    profile: Option<PathBuf>,
    /// With --scans: points farther than this (m) are beams that returned
    /// nothing, clearing free space up to it (graph2tree's -m) [default:
    /// every point is a hit].
    #[arg(long, requires = "scans")]
    max_range: Option<f64>,
    /// With --scans: angular bin width of the OPDF grids (degrees) [default:
    /// the median spacing of neighbouring points, a regular scanner's step].
    #[arg(long, requires = "scans")]
    angular_step: Option<f64>,
    /// Pool each scan's beams on the surfaces they share (docs/math.md
    /// §5.5), for every method: faces (large planar faces only), windows
    /// (every beam's 3x3 neighbourhood too) or off [default: the
    /// experiment's `beam_pooling`; with --scans off].
    #[arg(long, value_parser = pooling_parser())]
    beam_pooling: Option<crate::mapping::pooling::Pooling>,
    /// OPDF methods: sample the surface between neighbouring beams whose
    /// 3x3 window is one plane (docs/math.md §5.4): on (also the flag alone)
    /// or off [default: the experiment's `interpolate_beams`; with --scans
    /// off].
    #[arg(long, num_args = 0..=1, default_missing_value = "on", value_parser = ["on", "off"])]
    interpolate_beams: Option<String>,
    /// OPDF methods: the risk level ε of the cell model (docs/math.md
    /// §5.4), a probability up to 0.5, or off [default: the experiment's
    /// `risk`; with --scans 0.5, the experiments' default (§5.7)].
    #[arg(long, value_parser = risk_parser)]
    risk: Option<RiskArg>,
    #[command(flatten)]
    depth: DepthArgs,
    #[command(flatten)]
    run: RunOptions,
}

/// How `--scans DIR`, a folder of depth images, is read.
#[derive(Args, Debug)]
pub(crate) struct DepthArgs {
    /// With --scans DIR (depth images): the camera's fx,fy,cx,cy in pixels
    /// [default: 525,525,319.5,239.5, the TUM RGB-D benchmark's].
    #[arg(long, requires = "scans", value_parser = parse::parse_intrinsics, allow_hyphen_values = true)]
    intrinsics: Option<[f64; 4]>,
    /// With --scans DIR: the raw depth of one metre [default: 5000, TUM's].
    #[arg(long, requires = "scans")]
    depth_scale: Option<f64>,
    /// With --scans DIR: the camera's trajectory, `timestamp tx ty tz qx qy
    /// qz qw` lines (TUM format) [default: DIR/groundtruth.txt].
    #[arg(long, requires = "scans")]
    trajectory: Option<PathBuf>,
    /// With --scans DIR: read every N-th image (of those with a pose)
    /// [default: 1].
    #[arg(long, requires = "scans")]
    every: Option<usize>,
}

impl DepthArgs {
    /// The options these arguments give.
    fn options(&self) -> crate::experiment::run::depth_folder::DepthImages {
        use crate::experiment::run::depth_folder::DepthImages;
        let default = DepthImages::default();
        let mut camera = default.camera;
        if let Some([fx, fy, cx, cy]) = self.intrinsics {
            (camera.fx, camera.fy, camera.cx, camera.cy) = (fx, fy, cx, cy);
        }
        camera.scale = self.depth_scale.unwrap_or(camera.scale);
        DepthImages {
            camera,
            trajectory: self.trajectory.clone(),
            every: self.every.unwrap_or(default.every),
        }
    }
}

#[derive(Args, Debug)]
pub(crate) struct RunOptions {
    /// Seed of the run [default: the experiment's `seed`].
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (0: one per core). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// No progress bar or summary.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args, Debug)]
pub(crate) struct RunArgs {
    /// The experiment file (TOML).
    experiment: PathBuf,
    /// Output folder [default: results/<experiment>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Redo every run, discarding earlier results.
    #[arg(long)]
    fresh: bool,
    /// Run only shard i of n (1-based): every n-th run of the fixed list of
    /// (cell, seed); join the shards' folders with `sigmap merge`.
    #[arg(long, value_parser = parse_shard)]
    shard: Option<(usize, usize)>,
    /// Take over the folder's lock held by a process of another host (a
    /// shared filesystem), once you know that process has ended.
    #[arg(long)]
    break_lock: bool,
    #[command(flatten)]
    run: BatchOptions,
}

/// How `sigmap run` runs (its seeds are the experiment's `seeds`).
#[derive(Args, Debug)]
pub(crate) struct BatchOptions {
    /// Worker threads (0: one per core). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// No progress bar or summary.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args, Debug)]
pub(crate) struct OpdfArgs {
    /// Surface thickness Δ, the finest voxel edge (m).
    #[arg(long, default_value_t = 0.01)]
    thickness: f64,
    /// Measured range of the plotted surface (m).
    #[arg(long, default_value_t = 0.5)]
    range: f64,
    /// Output folder [default: results/opdf].
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub(crate) struct SimulateArgs {
    /// The experiment file (TOML).
    experiment: PathBuf,
    /// Output folder [default: results/<experiment>/scans].
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    run: RunOptions,
}

#[derive(Args, Debug)]
pub(crate) struct ExportArgs {
    /// The experiment file (TOML).
    experiment: PathBuf,
    /// Sweep cell (0-based, in the order of summary.csv) [default: the base experiment].
    #[arg(long)]
    cell: Option<usize>,
    /// Output folder [default: results/<experiment>/export].
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    run: RunOptions,
}

#[derive(Args, Debug)]
pub(crate) struct ScoreArgs {
    /// The map, .bt or .ot, in the run's map frame at the experiment's resolution.
    map: PathBuf,
    /// The experiment file (TOML) whose run the map is of (or --scene and --scans).
    #[arg(required_unless_present = "scene")]
    experiment: Option<PathBuf>,
    /// Score against this scene (TOML) instead: its solids are the ground
    /// truth, placed in the map frame by --scene-pose, at the map's resolution.
    #[arg(long, requires = "scans", conflicts_with_all = ["experiment", "cell"])]
    scene: Option<PathBuf>,
    /// With --scene: the recorded scans (an OctoMap ScanGraph, a scan log or
    /// a folder of depth images, as `map --scans` reads them) the map was
    /// built from; the cells their rays crossed or ended in are the ones
    /// scored.
    #[arg(long, requires = "scene")]
    scans: Option<PathBuf>,
    /// With --scene: where the scene stands in the map frame,
    /// x,y,z,roll,pitch,yaw (m, rad; fixed-axis roll-pitch-yaw as in URDF)
    /// [default: 0,0,0,0,0,0].
    #[arg(long, requires = "scene", value_parser = parse_pose, allow_hyphen_values = true)]
    scene_pose: Option<[f64; 6]>,
    /// With --scene: scan points farther than this from their origin are
    /// beams that returned nothing (as graph2tree -m and sigmap export have
    /// them); default: every point is a hit.
    #[arg(long, requires = "scene", allow_hyphen_values = true)]
    max_range: Option<f64>,
    /// Sweep cell (0-based, in the order of summary.csv) [default: the base experiment].
    #[arg(long)]
    cell: Option<usize>,
    /// Append the row to this CSV (runs.csv columns; created if absent).
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Write the scored cells the map calls wrongly (false-free and
    /// false-occupied), their centres in the map frame: FILE.csv (a table:
    /// x,y,z,error,log_odds,probability), FILE.ply (points coloured by
    /// error, for CloudCompare or MeshLab) or FILE.ot (an OctoMap
    /// ColorOcTree of the cells coloured by error, for octovis).
    #[arg(long, value_name = "FILE")]
    errors: Option<PathBuf>,
    #[command(flatten)]
    depth: DepthArgs,
    #[command(flatten)]
    run: RunOptions,
}

#[derive(Args, Debug)]
pub(crate) struct PropagateArgs {
    /// The chain file (TOML; see docs/cli.md, "Chain file").
    chain: PathBuf,
    /// The measured point `x,y,z` in the last frame (m), replacing the file's
    /// `[point]` mean (its covariance is kept; zero if the file has none).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    point: Option<[f64; 3]>,
    /// The unscented transform with the scaled sigma-point set of this α
    /// (docs/math.md §3.2) instead of the paper's set.
    #[arg(long)]
    alpha: Option<f64>,
    /// The scaled set's β (with --alpha; 2 is optimal for Gaussian inputs).
    #[arg(long, requires = "alpha", default_value_t = crate::uncertainty::unscented::DEFAULT_BETA)]
    beta: f64,
    /// The scaled set's κ (with --alpha).
    #[arg(long, requires = "alpha", default_value_t = 0.0)]
    kappa: f64,
    /// Monte Carlo draws.
    #[arg(long, default_value_t = 10_000)]
    samples: usize,
    /// Monte Carlo seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print JSON (the stable schema of docs/cli.md) instead of a table.
    #[arg(long)]
    json: bool,
    /// Sweep every link's rotation sigma from 0.001 to 0.2 rad and write each
    /// method's covariance error against Monte Carlo as CSV and SVG.
    #[arg(long)]
    sweep: bool,
    /// Number of rotation sigmas in the sweep.
    #[arg(long, default_value_t = 20)]
    sweep_points: usize,
    /// Output folder of the sweep [default: results/<chain file stem>_sweep].
    #[arg(long)]
    out: Option<PathBuf>,
}

/// The line that says why the defaults' surface samples between beams are
/// off for `experiment`, if they are (docs/math.md §5.7).
pub(crate) fn samples_note(experiment: &crate::experiment::Experiment) -> Option<String> {
    experiment.samples_over_budget().map(|beams| {
        format!(
            "note: surface samples between beams are off: {beams} beams per viewpoint are more \
             than sigmap samples (set interpolate_beams = \"off\" to say so, or use larger \
             sensor steps to have them)"
        )
    })
}

/// Prints `notes` (the input files' `note: …` lines) on stderr unless
/// `quiet`.
pub(crate) fn print_notes(notes: &[String], quiet: bool) {
    if !quiet {
        for note in notes {
            eprintln!("{note}");
        }
    }
}

/// Runs `f` on a rayon pool of `threads` workers (0: one per core).
pub(crate) fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> Result<T> {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    if threads > 8 * cores.max(8) {
        return Err(Error::Usage(format!(
            "--threads {threads}: this machine has {cores} cores; use at most {} (0: one per core)",
            8 * cores.max(8)
        )));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::Usage(format!("cannot start {threads} threads: {e}")))?;
    Ok(pool.install(f))
}

/// An error of a sweep cell the experiment does not have names `--cell`.
pub(crate) fn cell_flag(e: Error) -> Error {
    if e.to_string().contains("sweep cells (0 to") {
        e.context("--cell: ")
    } else {
        e
    }
}

pub(crate) fn progress_bar(len: usize, what: &str, quiet: bool) -> ProgressBar {
    // Built, not set: nothing is drawn before the first length or step (a
    // bar of unknown length would flash full, "0/0").
    let mut bar = ProgressBar::new(len as u64).with_message(what.to_string());
    if quiet || !std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    if let Ok(style) =
        ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} {elapsed} (eta {eta})")
    {
        bar = bar.with_style(style.progress_chars("=> "));
    }
    bar
}

/// Parses the command line, runs the command, and returns the exit code.
pub fn main() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            // A bad value or an unknown flag is one line naming the flag
            // and what is wrong (with the possible values); other usage
            // errors keep clap's usage lines.
            let one_line = [
                ErrorKind::ValueValidation,
                ErrorKind::InvalidValue,
                ErrorKind::UnknownArgument,
            ];
            if one_line.contains(&e.kind()) {
                let text = e.render().to_string();
                let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
                let first = lines.next().unwrap_or_default();
                let values = lines.find(|l| l.starts_with("[possible values"));
                match (e.kind(), values) {
                    (ErrorKind::UnknownArgument, _) => {
                        eprintln!("{first} (--help lists the flags)");
                    }
                    (_, Some(values)) => eprintln!("{first} {values}"),
                    _ => eprintln!("{first}"),
                }
            } else {
                let _ = e.print();
            }
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    exit_code_of(move || dispatch(cli.command))
}

/// Runs a command and gives the process's exit code: 0, or its error's
/// (printed as one line). A panic is a bug: its message (printed by the
/// hook) and the internal failure's code, never one that reads as bad input
/// or a failed check.
fn exit_code_of(command: impl FnOnce() -> Result<()> + std::panic::UnwindSafe) -> i32 {
    let Ok(result) = std::panic::catch_unwind(command) else {
        eprintln!(
            "error: internal error (a bug in sigmap; please report it with the command line)"
        );
        return crate::error::EXIT_INTERNAL;
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}

/// Runs one command.
fn dispatch(command: Command) -> Result<()> {
    match command {
        Command::Run(args) => run::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Export(args) => export::run(args),
        Command::Score(args) => score::run(args),
        Command::Propagate(args) => propagate::run(args),
        Command::Opdf(args) => opdf::run(args),
        Command::Map(args) => map::run(args),
        Command::GroundTruth(args) => ground_truth::run(args),
        Command::Regress(args) => regress::run(args),
        Command::Merge(args) => run::merge(args),
        Command::Submit(args) => cluster::submit(args),
        Command::Status(args) => cluster::status(args),
    }
}

#[cfg(test)]
mod exit_code_tests {
    use super::*;
    use crate::error::EXIT_INTERNAL;

    #[test]
    fn each_kind_of_failure_has_its_own_exit_code() {
        assert_eq!(exit_code_of(|| Ok(())), 0);
        assert_eq!(
            exit_code_of(|| Err(Error::CheckFailed("F1 fell".into()))),
            1
        );
        assert_eq!(exit_code_of(|| Err(Error::input("a.toml", "bad"))), 2);
        assert_eq!(exit_code_of(|| Err(Error::Usage("--x".into()))), 2);
        assert_eq!(exit_code_of(|| Err(Error::Internal("poisoned".into()))), 3);
        assert_eq!(exit_code_of(|| panic!("a bug")), EXIT_INTERNAL);
    }
}
