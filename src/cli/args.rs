//! The command line's arguments: the `sigmap` parser ([`Cli`]), its
//! commands and each command's flags, with their help texts (clap derive).
//! The adapters in the sibling files read them.

use super::parse::{
    self, method_parser, parse_point, parse_pose, parse_shard, parse_tasks, pooling_parser,
    risk_parser,
};
use super::RiskArg;
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// Simulation-backed evaluation of uncertainty-aware occupancy maps.
#[derive(Parser, Debug)]
#[command(name = "sigmap", version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(Subcommand, Debug)]
pub(crate) enum Command {
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
    pub(crate) experiment: PathBuf,
    /// Number of array tasks (shards), 1 to 10000.
    #[arg(long, default_value_t = 1, value_parser = parse_tasks)]
    pub(crate) tasks: usize,
    /// Results folder on the shared filesystem [default: results/<experiment>].
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    /// An extra argument for sbatch (partition, time, memory...), repeatable:
    /// --sbatch-arg=--partition=short --sbatch-arg=--time=01:00:00.
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) sbatch_arg: Vec<String>,
    /// Submit only the shards with missing runs (and the merge).
    #[arg(long)]
    pub(crate) resume: bool,
}

#[derive(Args, Debug)]
pub(crate) struct StatusArgs {
    /// The results folder of a submission.
    pub(crate) dir: PathBuf,
}

#[derive(Args, Debug)]
pub(crate) struct MergeArgs {
    /// The experiment file the shards ran.
    pub(crate) experiment: PathBuf,
    /// The shards' output folders.
    #[arg(required = true)]
    pub(crate) shards: Vec<PathBuf>,
    /// Output folder [default: results/<experiment>].
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub(crate) struct RegressArgs {
    /// The current summary.csv.
    pub(crate) current: PathBuf,
    /// The baseline summary.csv (this, `--consistent`, or both).
    #[arg(long)]
    pub(crate) baseline: Option<PathBuf>,
    /// Override a metric's tolerance: METRIC=VALUE (absolute), repeatable.
    /// Defaults: 0.01 for scores in [0, 1]; 5% of the baseline for anees and log_loss.
    #[arg(long)]
    pub(crate) tolerance: Vec<String>,
    /// Fail unless METHOD's covariances are consistent in every cell: its
    /// mean NEES of one point a run within the 95% band honest covariances
    /// give it; repeatable.
    #[arg(long, value_name = "METHOD")]
    pub(crate) consistent: Vec<String>,
}

#[derive(Args, Debug)]
pub(crate) struct GroundTruthArgs {
    /// The scene file (TOML).
    pub(crate) scene: PathBuf,
    /// Finest voxel edge (m).
    #[arg(long, default_value_t = 0.01)]
    pub(crate) resolution: f64,
    /// Output file, .bt or .ot.
    #[arg(long)]
    pub(crate) out: PathBuf,
}

#[derive(Args, Debug)]
pub(crate) struct MapArgs {
    /// The experiment file (TOML); or give recorded scans with --scans.
    #[arg(required_unless_present = "scans")]
    pub(crate) experiment: Option<PathBuf>,
    /// blind, jacobian, unscented, correlated, ray_update or
    /// ray_update_discrete (OctoMap's insertion with discretize = true); or
    /// registered_truth (the truth as the run's scene registration places
    /// it), consensus_truth (as its scans together place it) or
    /// registration_belief (the registered truth blurred over the
    /// registration's covariance; none of the three for --scans).
    #[arg(long, default_value = "unscented", value_parser = method_parser())]
    pub(crate) method: crate::mapping::Method,
    /// Finest voxel edge (m) [default: the experiment's `resolution`; with
    /// --scans 0.1, as graph2tree].
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) resolution: Option<f64>,
    /// Sweep cell (0-based, in the order of summary.csv) [default: the base
    /// experiment]: with --seed, the map `sigmap run` builds for that cell
    /// and seed.
    #[arg(long, conflicts_with = "scans")]
    pub(crate) cell: Option<usize>,
    /// With a truth reference (registered_truth, consensus_truth,
    /// registration_belief): compute it over the box of cells the run's
    /// scans observe, the rest unknown, as `sigmap run` computes and writes
    /// it [default: the whole workspace].
    #[arg(long, conflicts_with = "scans")]
    pub(crate) observed: bool,
    /// Map file, .bt or .ot [default: results/<experiment>/map_<method>.bt;
    /// required with --scans].
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    /// Also write the rays (origins and end points) for OctoMap's benchmark:
    /// the rays the ray update inserts (with beam pooling, the pooled points).
    #[arg(long, conflicts_with = "scans")]
    pub(crate) export_rays: Option<PathBuf>,
    /// Map scans recorded elsewhere: an OctoMap ScanGraph (.graph, e.g. from
    /// log2graph or `sigmap export`), the plain-text log log2graph reads
    /// (`NODE x y z roll pitch yaw` lines, each followed by `x y z` lines),
    /// points in each node's sensor frame, or a folder of depth images in
    /// the TUM RGB-D layout (depth.txt, groundtruth.txt, depth/*.png).
    #[arg(long, conflicts_with = "experiment", requires = "profile")]
    pub(crate) scans: Option<PathBuf>,
    /// With --scans: the error profile (TOML) the scans are believed with;
    /// its [world_from_robot] is the error of each node's pose.
    #[arg(long, requires = "scans")]
    pub(crate) profile: Option<PathBuf>,
    /// With --scans: points farther than this (m) are beams that returned
    /// nothing, clearing free space up to it (graph2tree's -m) [default:
    /// every point is a hit].
    #[arg(long, requires = "scans")]
    pub(crate) max_range: Option<f64>,
    /// With --scans: angular bin width of the OPDF grids (degrees) [default:
    /// the median spacing of neighbouring points, a regular scanner's step].
    #[arg(long, requires = "scans")]
    pub(crate) angular_step: Option<f64>,
    /// Pool each scan's beams on the surfaces they share (docs/math.md
    /// §5.5), for every method: faces (large planar faces only), windows
    /// (every beam's 3x3 neighbourhood too) or off [default: the
    /// experiment's `beam_pooling`; with --scans off].
    #[arg(long, value_parser = pooling_parser())]
    pub(crate) beam_pooling: Option<crate::mapping::pooling::Pooling>,
    /// OPDF methods: sample the surface between neighbouring beams whose
    /// 3x3 window is one plane (docs/math.md §5.4): on (also the flag alone)
    /// or off [default: the experiment's `interpolate_beams`; with --scans
    /// off].
    #[arg(long, num_args = 0..=1, default_missing_value = "on", value_parser = ["on", "off"])]
    pub(crate) interpolate_beams: Option<String>,
    /// OPDF methods: the risk level ε of the cell model (docs/math.md
    /// §5.4), a probability up to 0.5, or off [default: the experiment's
    /// `risk`; with --scans 0.5, the experiments' default (§5.7)].
    #[arg(long, value_parser = risk_parser)]
    pub(crate) risk: Option<RiskArg>,
    #[command(flatten)]
    pub(crate) depth: DepthArgs,
    #[command(flatten)]
    pub(crate) run: RunOptions,
}

/// How `--scans DIR`, a folder of depth images, is read.
#[derive(Args, Debug)]
pub(crate) struct DepthArgs {
    /// With --scans DIR (depth images): the camera's fx,fy,cx,cy in pixels
    /// [default: 525,525,319.5,239.5, the TUM RGB-D benchmark's].
    #[arg(long, requires = "scans", value_parser = parse::parse_intrinsics, allow_hyphen_values = true)]
    pub(crate) intrinsics: Option<[f64; 4]>,
    /// With --scans DIR: the raw depth of one metre [default: 5000, TUM's].
    #[arg(long, requires = "scans")]
    pub(crate) depth_scale: Option<f64>,
    /// With --scans DIR: the camera's trajectory, `timestamp tx ty tz qx qy
    /// qz qw` lines (TUM format) [default: DIR/groundtruth.txt].
    #[arg(long, requires = "scans")]
    pub(crate) trajectory: Option<PathBuf>,
    /// With --scans DIR: read every N-th image (of those with a pose)
    /// [default: 1].
    #[arg(long, requires = "scans")]
    pub(crate) every: Option<usize>,
}

impl DepthArgs {
    /// The options these arguments give.
    pub(crate) fn options(&self) -> crate::experiment::run::depth_folder::DepthImages {
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
    pub(crate) seed: Option<u64>,
    /// Worker threads (0: one per core). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    pub(crate) threads: usize,
    /// No progress bar or summary.
    #[arg(long, short)]
    pub(crate) quiet: bool,
}

#[derive(Args, Debug)]
pub(crate) struct RunArgs {
    /// The experiment file (TOML).
    pub(crate) experiment: PathBuf,
    /// Output folder [default: results/<experiment>].
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    /// Redo every run, discarding earlier results.
    #[arg(long)]
    pub(crate) fresh: bool,
    /// Run only shard i of n (1-based): every n-th run of the fixed list of
    /// (cell, seed); join the shards' folders with `sigmap merge`.
    #[arg(long, value_parser = parse_shard)]
    pub(crate) shard: Option<(usize, usize)>,
    /// Take over the folder's lock held by a process of another host (a
    /// shared filesystem), once you know that process has ended.
    #[arg(long)]
    pub(crate) break_lock: bool,
    #[command(flatten)]
    pub(crate) run: BatchOptions,
}

/// How `sigmap run` runs (its seeds are the experiment's `seeds`).
#[derive(Args, Debug)]
pub(crate) struct BatchOptions {
    /// Worker threads (0: one per core). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    pub(crate) threads: usize,
    /// No progress bar or summary.
    #[arg(long, short)]
    pub(crate) quiet: bool,
}

#[derive(Args, Debug)]
pub(crate) struct OpdfArgs {
    /// Surface thickness Δ, the finest voxel edge (m).
    #[arg(long, default_value_t = 0.01)]
    pub(crate) thickness: f64,
    /// Measured range of the plotted surface (m).
    #[arg(long, default_value_t = 0.5)]
    pub(crate) range: f64,
    /// Output folder [default: results/opdf].
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub(crate) struct SimulateArgs {
    /// The experiment file (TOML).
    pub(crate) experiment: PathBuf,
    /// Output folder [default: results/<experiment>/scans].
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) run: RunOptions,
}

#[derive(Args, Debug)]
pub(crate) struct ExportArgs {
    /// The experiment file (TOML).
    pub(crate) experiment: PathBuf,
    /// Sweep cell (0-based, in the order of summary.csv) [default: the base experiment].
    #[arg(long)]
    pub(crate) cell: Option<usize>,
    /// Output folder [default: results/<experiment>/export].
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) run: RunOptions,
}

#[derive(Args, Debug)]
pub(crate) struct ScoreArgs {
    /// The map, .bt or .ot, in the run's map frame at the experiment's resolution.
    pub(crate) map: PathBuf,
    /// The experiment file (TOML) whose run the map is of (or --scene and --scans).
    #[arg(required_unless_present = "scene")]
    pub(crate) experiment: Option<PathBuf>,
    /// Score against this scene (TOML) instead: its solids are the ground
    /// truth, placed in the map frame by --scene-pose, at the map's resolution.
    #[arg(long, requires = "scans", conflicts_with_all = ["experiment", "cell"])]
    pub(crate) scene: Option<PathBuf>,
    /// With --scene: the recorded scans (an OctoMap ScanGraph, a scan log or
    /// a folder of depth images, as `map --scans` reads them) the map was
    /// built from; the cells their rays crossed or ended in are the ones
    /// scored.
    #[arg(long, requires = "scene")]
    pub(crate) scans: Option<PathBuf>,
    /// With --scene: where the scene stands in the map frame,
    /// x,y,z,roll,pitch,yaw (m, rad; fixed-axis roll-pitch-yaw as in URDF)
    /// [default: 0,0,0,0,0,0].
    #[arg(long, requires = "scene", value_parser = parse_pose, allow_hyphen_values = true)]
    pub(crate) scene_pose: Option<[f64; 6]>,
    /// With --scene: scan points farther than this from their origin are
    /// beams that returned nothing (as graph2tree -m and sigmap export have
    /// them); default: every point is a hit.
    #[arg(long, requires = "scene", allow_hyphen_values = true)]
    pub(crate) max_range: Option<f64>,
    /// Sweep cell (0-based, in the order of summary.csv) [default: the base experiment].
    #[arg(long)]
    pub(crate) cell: Option<usize>,
    /// Append the row to this CSV (runs.csv columns; created if absent).
    #[arg(long)]
    pub(crate) csv: Option<PathBuf>,
    /// Write the scored cells the map calls wrongly (false-free and
    /// false-occupied), their centres in the map frame: FILE.csv (a table:
    /// x,y,z,error,log_odds,probability), FILE.ply (points coloured by
    /// error, for CloudCompare or MeshLab) or FILE.ot (an OctoMap
    /// ColorOcTree of the cells coloured by error, for octovis).
    #[arg(long, value_name = "FILE")]
    pub(crate) errors: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) depth: DepthArgs,
    #[command(flatten)]
    pub(crate) run: RunOptions,
}

#[derive(Args, Debug)]
pub(crate) struct PropagateArgs {
    /// The chain file (TOML; see docs/cli.md, "Chain file").
    pub(crate) chain: PathBuf,
    /// The measured point `x,y,z` in the last frame (m), replacing the file's
    /// `[point]` mean (its covariance is kept; zero if the file has none).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub(crate) point: Option<[f64; 3]>,
    /// The unscented transform with the scaled sigma-point set of this α
    /// (docs/math.md §3.2) instead of the paper's set.
    #[arg(long)]
    pub(crate) alpha: Option<f64>,
    /// The scaled set's β (with --alpha; 2 is optimal for Gaussian inputs).
    #[arg(long, requires = "alpha", default_value_t = crate::uncertainty::unscented::DEFAULT_BETA)]
    pub(crate) beta: f64,
    /// The scaled set's κ (with --alpha).
    #[arg(long, requires = "alpha", default_value_t = 0.0)]
    pub(crate) kappa: f64,
    /// Monte Carlo draws.
    #[arg(long, default_value_t = 10_000)]
    pub(crate) samples: usize,
    /// Monte Carlo seed.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Print JSON (the stable schema of docs/cli.md) instead of a table.
    #[arg(long)]
    pub(crate) json: bool,
    /// Sweep every link's rotation sigma from 0.001 to 0.2 rad and write each
    /// method's covariance error against Monte Carlo as CSV and SVG.
    #[arg(long)]
    pub(crate) sweep: bool,
    /// Number of rotation sigmas in the sweep.
    #[arg(long, default_value_t = 20)]
    pub(crate) sweep_points: usize,
    /// Output folder of the sweep [default: results/<chain file stem>_sweep].
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
}
