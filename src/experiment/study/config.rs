//! The experiment file: what is simulated (scene, robot and mount, sensor,
//! error profile, viewpoints, seed). Paths are relative to the experiment file.

use crate::error::{read_toml_with, Error, Result};
use crate::experiment::run::registration_belief::BeliefSettings;
use crate::experiment::study::run_method::RunMethod;
use crate::geometry::{Isometry3, Pose, Vector3};
use crate::mapping::scan::{check_sample_budget, Layouts, MapperView};
use crate::mapping::settings::MapSettings;
use crate::sim::believed::BelievedErrors;
use crate::sim::ik::{self, IkFailure, IkOptions, IkTarget};
use crate::sim::profile::ErrorProfile;
use crate::sim::robot::{KinematicChain, Robot};
use crate::sim::scene::Scene;
use crate::sim::sensor::Scanner;
use crate::sim::streams::{Stream, Streams};
use crate::uncertainty::SigmaSet;
use file::ViewpointSpec;
use nalgebra::Unit;
use rand::Rng;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// One sweep axis: a numeric field and the values it takes. Fields:
/// `pose_error_scale` (multiplies every pose-error sigma of the profile),
/// `experiment.<path>`, `profile.<path>` or `scene.<path>` (a number in that
/// file, by dotted path, e.g. `experiment.sensor.max_range`,
/// `profile.range.sigma0`, `scene.object.2.radius`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SweepAxis {
    /// The field.
    pub field: String,
    /// Its values: numbers, or strings for string fields such as
    /// `experiment.error_profile` or `experiment.scene`.
    pub values: Vec<SweepValue>,
    /// One of `values` that the others are paired against, method by method
    /// and seed by seed (`paired.csv` rows whose `reference_cell` differs
    /// from their `cell`): what changing this field alone does to each
    /// method. Without it the axis is only swept.
    #[serde(default)]
    pub reference: Option<SweepValue>,
}

/// A sweep value.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged, expecting = "a sweep value: a number or a string")]
pub enum SweepValue {
    /// A number.
    Number(f64),
    /// A string (a file path, for example).
    Text(String),
}

impl std::fmt::Display for SweepValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SweepValue::Number(v) => write!(f, "{v}"),
            SweepValue::Text(t) => f.write_str(t),
        }
    }
}

impl SweepValue {
    fn to_toml(&self) -> toml::Value {
        match self {
            SweepValue::Number(v) => toml::Value::Float(*v),
            SweepValue::Text(t) => toml::Value::String(t.clone()),
        }
    }
}

/// A resolved viewpoint: a joint configuration within the limits.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewpoint {
    /// How the file asked for it.
    pub request: String,
    /// Nominal joint values (rad, m).
    pub joints: Vec<f64>,
}

/// Values that replace an experiment file's own (`sigmap map
/// --resolution`, `--seed`, `--method`, ...), checked exactly as the file's
/// are when the experiment is loaded ([`Experiment::load_with`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides {
    /// The map's finest voxel edge (m).
    pub resolution: Option<f64>,
    /// The run's seed (`seed`).
    pub seed: Option<u64>,
    /// `beam_pooling`.
    pub beam_pooling: Option<crate::mapping::pooling::Pooling>,
    /// `interpolate_beams`.
    pub interpolate_beams: Option<bool>,
    /// `risk` (`Some(None)`: off).
    pub risk: Option<Option<f64>>,
    /// `methods` (sigmap's own; the `[[mapper]]` tables still join them).
    pub methods: Option<Vec<crate::mapping::Method>>,
    /// `grid_offset`.
    pub grid_offset: Option<bool>,
}

impl Overrides {
    /// The paper's map configuration whatever the file says: raw beams, no
    /// surface samples, no risk level (sigmap's defaults are otherwise,
    /// docs/math.md §5.7).
    pub fn paper_configuration() -> Self {
        Self {
            beam_pooling: Some(crate::mapping::pooling::Pooling::Off),
            interpolate_beams: Some(false),
            risk: Some(None),
            ..Self::default()
        }
    }
}

/// A loaded and checked experiment.
pub struct Experiment {
    /// Its name (the results folder is `results/<name>/`).
    name: String,
    /// Free text.
    description: String,
    /// The experiment file.
    source: PathBuf,
    /// The run's seed.
    seed: u64,
    /// The map's finest voxel edge (m): `resolution` in the file, default 0.01.
    resolution: f64,
    /// Whether the scene sits at a sub-voxel offset drawn from each run's seed
    /// (`grid_offset = true`), so that no face lies on a cell plane by design.
    grid_offset: bool,
    /// How maps are built: OctoMap's hit, miss and clamp (`[map]`), the
    /// cell model's bounds (`[map]`) and risk level ε (`risk`), beam pooling
    /// (`beam_pooling`; §5.5), surface samples between beams
    /// (`interpolate_beams`) and their gate (`sample_gate`; §5.4). What the
    /// file leaves out: OctoMap's and the paper's values for `[map]`, and
    /// for the other four the uncertainty-aware maps' defaults (docs/math.md
    /// §5.7), the ray update keeping OctoMap's raw rays.
    map: MapSettings,
    /// The beams per viewpoint of a raster too dense for the samples that
    /// the defaults would have added (`None`: no such raster, or samples
    /// set in the file).
    samples_over_budget: Option<usize>,
    /// The sigma-point set of the `unscented` and `correlated` methods: the
    /// paper's, or the scaled set of an `[unscented]` table (docs/math.md
    /// §3.2).
    sigma_set: SigmaSet,
    /// The seeds of `sigmap run` (`seeds = [..]`, default `[seed]`).
    seeds: Vec<u64>,
    /// The modelling methods compared by `sigmap run`: `methods` (default
    /// blind, unscented, ray_update), then the `[[mapper]]` tables.
    methods: Vec<RunMethod>,
    /// The method every other one is paired against in `paired.csv`
    /// (`reference = ".."`; default `ray_update` when listed, else the
    /// first method).
    reference: RunMethod,
    /// Further methods every other one is also paired against
    /// (`also_paired = [..]`), after the reference.
    also_paired: Vec<RunMethod>,
    /// The workcell scene.
    scene: Scene,
    /// The robot.
    robot: Robot,
    /// `base_link -> flange_link`: the arm (T_rw = world_from_base · FK).
    arm: KinematicChain,
    /// `base_link -> sensor_link`, for inverse kinematics.
    sensor_chain: KinematicChain,
    /// Nominal `robot_from_camera` (T_cr): the URDF's flange → laser joints.
    robot_from_camera: Pose,
    /// Where the robot base stands in the world.
    world_from_base: Isometry3,
    /// Nominal `world_from_scene` (T_sw).
    world_from_scene: Pose,
    /// The scanner.
    scanner: Scanner,
    /// The error profile: what the simulator draws.
    profile: ErrorProfile,
    /// What the maps are told of its errors (`[believed]`, docs/math.md
    /// §6.7).
    believed: BelievedErrors,
    /// The profile `[believed]` names, if it names one: the errors the maps
    /// are told instead of `profile`'s.
    believed_profile: Option<ErrorProfile>,
    /// How the reference `registration_belief` is drawn and called.
    registration_belief: BeliefSettings,
    /// The viewpoints, resolved to joint configurations.
    viewpoints: Vec<Viewpoint>,
    /// The sweep axes (runs are their cartesian product times the seeds).
    sweep: Vec<SweepAxis>,
    /// The sweep values this experiment was loaded with (empty: the base).
    cell: Vec<(String, SweepValue)>,
    /// What the user should know of its files that is not an error
    /// ([`Experiment::notes`]).
    notes: Vec<String>,
}

impl Experiment {
    /// Reads an experiment and everything it names, solves the look-at
    /// viewpoints, and checks them. Every error names its file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_cell(path, &[])
    }

    /// Reads the experiment with its sweep cell number `cell` (0-based, in
    /// the order of [`Experiment::cells`]) applied; `None`: the base.
    pub fn load_cell_index(path: &Path, cell: Option<usize>) -> Result<Self> {
        Self::load_cell(path, &Self::cell_values(path, cell)?)
    }

    /// The values of the experiment's sweep cell number `cell` (0-based, in
    /// the order of [`Experiment::cells`]), to load it with
    /// ([`Experiment::load_with`]); `None`: none (the base experiment).
    pub fn cell_values(path: &Path, cell: Option<usize>) -> Result<Vec<(String, SweepValue)>> {
        let Some(k) = cell else {
            return Ok(Vec::new());
        };
        let cells = Self::load(path)?.cells();
        cells.get(k).cloned().ok_or_else(|| {
            Error::Usage(format!(
                "sweep cell {k}: the experiment has {} sweep cells (0 to {})",
                cells.len(),
                cells.len() - 1
            ))
        })
    }

    /// Reads the experiment with one sweep cell's values applied.
    pub fn load_cell(path: &Path, cell: &[(String, SweepValue)]) -> Result<Self> {
        Self::load_with(path, cell, &Overrides::default())
    }

    /// What a mapper may know of this experiment: the scanner's beam
    /// layout and reach, the range-error model, the map settings and the
    /// sigma-point set. Neither the scene nor any truth.
    pub fn mapper_view(&self) -> MapperView<'_> {
        MapperView {
            layouts: Layouts::Shared(&self.scanner.layout),
            range: self.believed.range(&self.believed_profile().range),
            max_range: self.scanner.max_range,
            settings: &self.map,
            sigma_set: self.sigma_set,
        }
    }

    /// Where the map's grid sits relative to the scene for the run with
    /// `seed`: `map = scene + offset`, each component uniform in
    /// `[0, resolution)` from the seed's own stream when `grid_offset` is on,
    /// zero otherwise. The same for every method of the seed.
    pub fn map_offset(&self, seed: u64) -> Vector3 {
        if !self.grid_offset {
            return Vector3::zeros();
        }
        let mut rng = Streams::new(seed).rng(Stream::GridOffset);
        Vector3::from_fn(|_, _| rng.random::<f64>() * self.resolution)
    }

    /// The sweep cells: the cartesian product of the axes' values, first axis
    /// outermost (one empty cell without a sweep).
    pub fn cells(&self) -> Vec<Vec<(String, SweepValue)>> {
        self.sweep.iter().fold(vec![Vec::new()], |cells, axis| {
            cells
                .iter()
                .flat_map(|cell| {
                    axis.values.iter().map(move |v| {
                        let mut c = cell.clone();
                        c.push((axis.field.clone(), v.clone()));
                        c
                    })
                })
                .collect()
        })
    }

    /// A cell's label in files: `field=value;field=value` (empty for the base).
    pub fn cell_label(cell: &[(String, SweepValue)]) -> String {
        cell.iter()
            .map(|(f, v)| format!("{f}={v}"))
            .collect::<Vec<_>>()
            .join(";")
    }

    /// Checks, before anything is allocated, that what a run is scored
    /// with stays within bounds: the observable mask (every beam out to
    /// `max_range`) and the ground truth, which spans what the beams can
    /// reach (the nominal sensor positions with `max_range` around them,
    /// cut to the workspace).
    pub fn check_truth_cost(&self) -> crate::error::Result<()> {
        use crate::geometry::{Point3, Vector3};
        let beams = (self.scanner.directions().len() * self.viewpoints.len()) as f64;
        let reach = self.scanner.max_range + self.resolution;
        // A viewpoint's rays stay in the cube of `reach` around its sensor:
        // a dense raster crosses the same cells many times over.
        let cube = (2.0 * reach / self.resolution + 1.0).powi(3);
        crate::eval::observable::check_mask_cost(
            beams * self.scanner.max_range / self.resolution,
            cube * self.viewpoints.len() as f64,
            self.resolution,
            &format!(
                "{beams:.0} beams out to max_range = {} m",
                self.scanner.max_range
            ),
        )
        .map_err(|e| Error::input(&self.source, e))?;
        let mut seen = crate::sim::scene::Bounds {
            min: Point3::from(Vector3::repeat(f64::INFINITY)),
            max: Point3::from(Vector3::repeat(f64::NEG_INFINITY)),
        };
        for viewpoint in &self.viewpoints {
            let sensor = self
                .nominal_scene_from_camera(&viewpoint.joints)
                .translation
                .vector;
            seen.min = seen.min.inf(&Point3::from(sensor - Vector3::repeat(reach)));
            seen.max = seen.max.sup(&Point3::from(sensor + Vector3::repeat(reach)));
        }
        self.scene.check_truth_region(
            &seen,
            self.resolution,
            "the workspace within max_range of the viewpoints",
        )
    }

    /// The nominal `scene_from_camera` at a joint configuration.
    pub fn nominal_scene_from_camera(&self, joints: &[f64]) -> Isometry3 {
        self.world_from_scene.to_isometry().inverse()
            * self.world_from_base
            * self.sensor_chain.forward_unchecked(joints)
    }

    fn resolve(&self, index: usize, spec: &ViewpointSpec) -> Result<Viewpoint> {
        let bad = |msg: String| Error::input(&self.source, msg);
        let viewpoint = match (&spec.joints, spec.look_at) {
            (Some(_), Some(_)) => return Err(bad("give `joints` or `look_at`, not both".into())),
            (None, None) => {
                return Err(bad(
                    "give `joints = [..]` (radians) or `look_at = [x, y, z]`".into(),
                ))
            }
            (Some(joints), None) => {
                if spec.distance.is_some() || spec.from.is_some() {
                    return Err(bad("`distance` and `from` go with `look_at`".into()));
                }
                self.arm
                    .check(joints)
                    .map_err(|e| e.context(format!("{}: ", self.source.display())))?;
                Viewpoint {
                    request: format!("joints {joints:?}"),
                    joints: joints.clone(),
                }
            }
            (None, Some(target)) => {
                let distance = spec
                    .distance
                    .ok_or_else(|| bad("`look_at` needs `distance` (m)".into()))?;
                let from = Vector3::from(spec.from.ok_or_else(|| {
                    bad("`look_at` needs `from = [x, y, z]`, the direction from the target toward the sensor".into())
                })?);
                if !(distance.is_finite() && distance > 0.0 && target.iter().all(|v| v.is_finite()))
                {
                    return Err(bad(format!(
                        "look_at {target:?} at distance {distance} is not a valid request"
                    )));
                }
                if !(from.iter().all(|v| v.is_finite()) && from.norm() > 1e-9) {
                    return Err(bad(format!(
                        "`from` {:?} is not a direction",
                        from.as_slice()
                    )));
                }
                let request = format!(
                    "look_at [{}, {}, {}] from [{}, {}, {}] at {distance} m",
                    target[0], target[1], target[2], from.x, from.y, from.z
                );
                // Scene frame -> base frame, through the nominal placements.
                let base_from_scene =
                    self.world_from_base.inverse() * self.world_from_scene.to_isometry();
                let from = from.normalize();
                let position = (base_from_scene
                    * nalgebra::Point3::from(Vector3::from(target) + from * distance))
                .coords;
                let goal = IkTarget::LookAt {
                    position,
                    boresight: Unit::new_normalize(base_from_scene * -from),
                };
                let options = IkOptions {
                    seed: index as u64,
                    ..IkOptions::default()
                };
                let joints = ik::solve(&self.sensor_chain, &goal, None, &options).map_err(|f| {
                    bad(self.unreachable(&request, &position, &f, options.restarts))
                })?;
                Viewpoint { request, joints }
            }
        };
        let origin = nalgebra::Point3::from(
            self.nominal_scene_from_camera(&viewpoint.joints)
                .translation
                .vector,
        );
        if let Some(object) = self.scene.object_containing(&origin) {
            let name = &self.scene.objects()[object].name;
            let millimetres = self
                .scene
                .oversized_mesh(object)
                .map_or(String::new(), |span| {
                    format!(
                        " (a mesh {span:.3} m across, far larger than the workspace: {})",
                        crate::sim::scene::MILLIMETRES
                    )
                });
            return Err(bad(format!(
                "{}: the sensor origin {:?} is inside object '{name}'{millimetres}",
                viewpoint.request,
                origin.coords.as_slice(),
            )));
        }
        Ok(viewpoint)
    }

    /// Why no configuration puts the sensor at `position` (base frame) for
    /// a look-at viewpoint, and what to change: a position beyond the arm's
    /// reach needs the target nearer; one within it is barred by the joint
    /// limits at that orientation (or lies too near the base), which `from`
    /// or `distance` move.
    fn unreachable(
        &self,
        request: &str,
        position: &Vector3,
        failure: &IkFailure,
        restarts: usize,
    ) -> String {
        let robot = &self.robot.name;
        let residual = format!(
            "best position error {:.4} m, orientation {:.4} rad, after {restarts} restarts",
            failure.position_error, failure.orientation_error
        );
        let (from_base, reach) = (position.norm(), self.sensor_chain.reach());
        if from_base > reach {
            format!(
                "{request} is out of reach for robot '{robot}': the sensor would stand {from_base:.3} m \
                 from its base, which it reaches to at most {reach:.3} m; move the target closer to \
                 the base or shorten `distance`"
            )
        } else {
            format!(
                "{request} is unreachable for robot '{robot}': the sensor would stand {from_base:.3} m \
                 from its base (its reach is at most {reach:.3} m), but no configuration within the \
                 joint limits puts it there looking along `from` ({residual}); change `from` or \
                 `distance`, or move the target away from the base if it is near"
            )
        }
    }
}

/// Most viewpoints per experiment.
pub const MAX_VIEWPOINTS: usize = 10_000;
/// Most beams per run (all viewpoints): a run's scans, their truth and one
/// map stay within a few GB.
pub const MAX_BEAMS_PER_RUN: f64 = 16_000_000.0;

/// Most seeds per experiment (a list or a range).
pub const MAX_SEEDS: usize = 100_000;

/// The reference of the paired comparisons: the method `named` (one of
/// sigmap's or a `[[mapper]]`), which `methods` must list; without a name
/// `ray_update` when listed, else the first method.
fn reference_method(
    named: Option<&str>,
    methods: &[RunMethod],
) -> std::result::Result<RunMethod, String> {
    let ray_update = RunMethod::Own(crate::mapping::Method::RayUpdate);
    match named {
        Some(name) => methods
            .iter()
            .find(|m| m.as_str() == name)
            .cloned()
            .ok_or_else(|| {
                let listed: Vec<&str> = methods.iter().map(RunMethod::as_str).collect();
                format!(
                    "reference = \"{name}\" is not one of `methods` or the [[mapper]] tables \
                     ({}); add it there or pick one of them",
                    listed.join(", ")
                )
            }),
        None if methods.contains(&ray_update) => Ok(ray_update),
        None => Ok(methods[0].clone()),
    }
}

/// The first value that appears twice.
fn first_repeat<T: PartialEq>(values: &[T]) -> Option<&T> {
    values
        .iter()
        .enumerate()
        .find(|(i, v)| values[..*i].contains(v))
        .map(|(_, v)| v)
}

mod access;
mod file;
mod load;
#[cfg(test)]
mod tests;
