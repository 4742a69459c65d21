//! The experiment file: what is simulated (scene, robot and mount, sensor,
//! error profile, viewpoints, seed). Paths are relative to the experiment file.

use super::run_method::RunMethod;
use crate::error::{read_toml_with, Error, Result};
use crate::geometry::{Isometry3, Pose, Vector3};
use crate::mapping::scan::{check_sample_budget, Layouts, MapperView};
use crate::mapping::settings::MapSettings;
use crate::sim::ik::{self, IkOptions, IkTarget};
use crate::sim::profile::ErrorProfile;
use crate::sim::robot::{KinematicChain, Robot};
use crate::sim::scene::Scene;
use crate::sim::sensor::Scanner;
use crate::sim::streams::{Stream, Streams};
use crate::uncertainty::SigmaSet;
use file::{ExperimentFile, ViewpointSpec};
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
}

/// A sweep value.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
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

/// A loaded and checked experiment.
pub struct Experiment {
    /// Its name (the results folder is `results/<name>/`).
    pub name: String,
    /// Free text.
    pub description: String,
    /// The experiment file.
    pub source: PathBuf,
    /// The run's seed.
    pub seed: u64,
    /// The map's finest voxel edge (m): `resolution` in the file, default 0.01.
    pub resolution: f64,
    /// Whether the scene sits at a sub-voxel offset drawn from each run's seed
    /// (`grid_offset = true`), so that no face lies on a cell plane by design.
    pub grid_offset: bool,
    /// How maps are built: OctoMap's hit, miss and clamp (`[map]`), the
    /// cell model's bounds (`[map]`) and risk level ε (`risk`, off when
    /// absent; docs/math.md §5.4), beam pooling (`beam_pooling =
    /// "faces"`, `"windows"` or `true`; §5.5) and surface samples between
    /// beams (`interpolate_beams = true`; §5.4). Defaults: OctoMap's and the
    /// paper's values, pooling and samples off.
    pub map: MapSettings,
    /// The sigma-point set of the `unscented` and `correlated` methods: the
    /// paper's, or the scaled set of an `[unscented]` table (docs/math.md
    /// §3.2).
    pub sigma_set: SigmaSet,
    /// The seeds of `sigmap run` (`seeds = [..]`, default `[seed]`).
    pub seeds: Vec<u64>,
    /// The modelling methods compared by `sigmap run`: `methods` (default
    /// blind, unscented, ray_update), then the `[[mapper]]` tables.
    pub methods: Vec<RunMethod>,
    /// The method every other one is paired against in `paired.csv`
    /// (`reference = ".."`; default `ray_update` when listed, else the
    /// first method).
    pub reference: RunMethod,
    /// The workcell scene.
    pub scene: Scene,
    /// The robot.
    pub robot: Robot,
    /// `base_link -> flange_link`: the arm (T_rw = world_from_base · FK).
    pub arm: KinematicChain,
    /// `base_link -> sensor_link`, for inverse kinematics.
    pub sensor_chain: KinematicChain,
    /// Nominal `robot_from_camera` (T_cr): the URDF's flange → laser joints.
    pub robot_from_camera: Pose,
    /// Where the robot base stands in the world.
    pub world_from_base: Isometry3,
    /// Nominal `world_from_scene` (T_sw).
    pub world_from_scene: Pose,
    /// The scanner.
    pub scanner: Scanner,
    /// The error profile.
    pub profile: ErrorProfile,
    /// The viewpoints, resolved to joint configurations.
    pub viewpoints: Vec<Viewpoint>,
    /// The sweep axes (runs are their cartesian product times the seeds).
    pub sweep: Vec<SweepAxis>,
    /// The sweep values this experiment was loaded with (empty: the base).
    pub cell: Vec<(String, SweepValue)>,
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
        let base = Self::load(path)?;
        let cells = base.cells();
        match cell {
            None => Ok(base),
            Some(k) if k < cells.len() => Self::load_cell(path, &cells[k]),
            Some(k) => Err(Error::Usage(format!(
                "--cell {k}: the experiment has {} sweep cells (0 to {})",
                cells.len(),
                cells.len() - 1
            ))),
        }
    }

    /// Reads the experiment with one sweep cell's values applied.
    pub fn load_cell(path: &Path, cell: &[(String, SweepValue)]) -> Result<Self> {
        let mut by_file: [Vec<(String, toml::Value)>; 3] = Default::default();
        let mut pose_scale = None;
        for (field, value) in cell {
            if let SweepValue::Number(v) = value {
                if !v.is_finite() {
                    return Err(Error::input(
                        path,
                        format!("sweep field '{field}': value {v} is not finite"),
                    ));
                }
            }
            let target = [("experiment.", 0), ("profile.", 1), ("scene.", 2)]
                .iter()
                .find_map(|(prefix, i)| {
                    field
                        .strip_prefix(prefix)
                        .map(|rest| (*i, rest.to_string()))
                });
            match (field.as_str(), target) {
                ("pose_error_scale", _) => match value {
                    SweepValue::Number(v) if *v >= 0.0 => pose_scale = Some(*v),
                    _ => {
                        return Err(Error::input(
                            path,
                            format!("pose_error_scale = {value} must be a number >= 0"),
                        ))
                    }
                },
                (_, Some((i, rest))) => by_file[i].push((rest, value.to_toml())),
                _ => {
                    return Err(Error::input(
                        path,
                        format!(
                        "unknown sweep field '{field}' (use pose_error_scale, experiment.<path>, \
                             profile.<path> or scene.<path>)"
                    ),
                    ))
                }
            }
        }
        let file: ExperimentFile = read_toml_with(path, &by_file[0])?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let bad = |msg: String| Error::input(path, msg);
        let scene = Scene::load_with(&dir.join(&file.scene), &by_file[2])?;
        let mut profile = ErrorProfile::load_with(&dir.join(&file.error_profile), &by_file[1])?;
        if let Some(scale) = pose_scale {
            profile.scale_pose_errors(scale);
        }
        let what = match pose_scale {
            Some(scale) => format!("at pose_error_scale = {scale:e}"),
            None => "the profile".into(),
        };
        profile
            .check_pose_magnitudes(&what)
            .map_err(|e| Error::input(&profile.source, e))?;
        for (i, axis) in file.sweeps.iter().enumerate() {
            if axis.values.is_empty() {
                return Err(bad(format!("[[sweep]] '{}' has no values", axis.field)));
            }
            if file.sweeps[..i].iter().any(|a| a.field == axis.field) {
                return Err(bad(format!("[[sweep]] '{}' is swept twice", axis.field)));
            }
            let labels: Vec<String> = axis
                .values
                .iter()
                .map(std::string::ToString::to_string)
                .collect();
            if let Some(label) = first_repeat(&labels) {
                return Err(bad(format!(
                    "[[sweep]] '{}' lists the value {label} more than once",
                    axis.field
                )));
            }
        }
        let robot = Robot::load(&dir.join(&file.robot.urdf))?;
        let mount = &file.robot;
        let arm = robot.chain(&mount.base_link, &mount.flange_link)?;
        let sensor_chain = robot.chain(&mount.base_link, &mount.sensor_link)?;
        let mount_chain = robot.chain(&mount.flange_link, &mount.sensor_link)?;
        if mount_chain.dof() != 0 {
            return Err(bad(format!(
                "[robot] the joints between '{}' and '{}' must all be fixed: they are the sensor mount T_cr",
                mount.flange_link, mount.sensor_link
            )));
        }
        let robot_from_camera = Pose::from_isometry(&mount_chain.forward_unchecked(&[]));
        if let crate::sim::profile::ArmError::Joints(s) = &profile.arm {
            if s.len() != arm.dof() {
                return Err(Error::input(
                    &profile.source,
                    format!(
                        "[world_from_robot] joint_sigma has {} values, the arm '{}' has {} joints",
                        s.len(),
                        robot.name,
                        arm.dof()
                    ),
                ));
            }
        }
        let base = Pose::new(mount.xyz, mount.rpy);
        let world_from_scene = Pose::new(file.world_from_scene.xyz, file.world_from_scene.rpy);
        if !base.is_finite() || !world_from_scene.is_finite() {
            return Err(bad(
                "[robot] and [world_from_scene] poses must be finite".into()
            ));
        }
        if !crate::mapping::octree::RESOLUTIONS.contains(&file.resolution) {
            return Err(bad(format!(
                "resolution = {} must be between 0.001 and 1 m",
                file.resolution
            )));
        }
        let pooling = file.beam_pooling.pooling().map_err(&bad)?;
        let mut map = MapSettings::new(&file.map, file.risk, pooling).map_err(&bad)?;
        map.interpolate_beams = file
            .interpolate_beams
            .on("interpolate_beams")
            .map_err(&bad)?;
        let sigma_set = match &file.unscented {
            Some(spec) => SigmaSet::scaled(spec.alpha, spec.beta, spec.kappa)
                .map_err(|e| bad(format!("[unscented] {e}")))?,
            None => SigmaSet::Paper,
        };
        let seeds = match &file.seeds {
            Some(spec) => spec.seeds(MAX_SEEDS as u64).map_err(&bad)?,
            None => vec![file.seed],
        };
        if seeds.len() > MAX_SEEDS {
            return Err(bad(format!(
                "`seeds` lists {} seeds; sigmap runs at most {MAX_SEEDS} seeds per experiment",
                seeds.len()
            )));
        }
        if seeds.is_empty() {
            return Err(bad("`seeds` is empty".into()));
        }
        if let Some(seed) = first_repeat(&seeds) {
            return Err(bad(format!("`seeds` lists {seed} more than once")));
        }
        let methods = match &file.methods {
            None => vec![
                crate::mapping::Method::Blind,
                crate::mapping::Method::Unscented,
                crate::mapping::Method::RayUpdate,
            ],
            Some(names) => names
                .iter()
                .map(|n| n.parse().map_err(&bad))
                .collect::<Result<Vec<_>>>()?,
        };
        if methods.is_empty() {
            return Err(bad("`methods` is empty".into()));
        }
        if let Some(method) = first_repeat(&methods) {
            return Err(bad(format!("`methods` lists {method} more than once")));
        }
        let builds_grids = methods.iter().any(|m| m.builds_grids());
        let mut methods: Vec<RunMethod> = methods.into_iter().map(RunMethod::Own).collect();
        let folder = path.parent().unwrap_or(Path::new("."));
        for spec in file.mappers {
            let taken: Vec<&str> = crate::mapping::Method::ALL
                .iter()
                .map(|m| m.as_str())
                .chain(methods.iter().map(RunMethod::as_str))
                .collect();
            let mapper = spec.check(folder, &taken).map_err(&bad)?;
            methods.push(RunMethod::External(std::sync::Arc::new(mapper)));
        }
        let reference = reference_method(file.reference.as_deref(), &methods).map_err(&bad)?;
        let scanner = file.sensor.build().map_err(bad)?;
        if file.viewpoints.is_empty() {
            return Err(bad("the experiment has no [[viewpoint]]".into()));
        }
        let beams = scanner.directions().len() as f64 * file.viewpoints.len() as f64;
        if file.viewpoints.len() > MAX_VIEWPOINTS || beams > MAX_BEAMS_PER_RUN {
            return Err(bad(format!(
                "{} viewpoints x {} beams = {beams:.3e} beams per run; sigmap handles at most \
                 {MAX_VIEWPOINTS} viewpoints and {MAX_BEAMS_PER_RUN:.0} beams per run \
                 (use fewer viewpoints or larger sensor steps)",
                file.viewpoints.len(),
                scanner.directions().len()
            )));
        }
        if map.interpolate_beams {
            check_sample_budget(scanner.directions().len() as f64).map_err(&bad)?;
        }
        crate::eval::ground_truth::check_resolution(&scene, file.resolution)?;
        if builds_grids {
            scanner.check_clearing(file.resolution).map_err(bad)?;
        }
        let mut experiment = Self {
            name: file.name.unwrap_or_else(|| crate::sim::scene::stem(path)),
            description: file.description,
            source: path.to_path_buf(),
            seed: file.seed,
            resolution: file.resolution,
            grid_offset: file.grid_offset,
            map,
            sigma_set,
            seeds,
            methods,
            reference,
            scene,
            robot,
            arm,
            sensor_chain,
            robot_from_camera,
            world_from_base: base.to_isometry(),
            world_from_scene,
            scanner,
            profile,
            viewpoints: Vec::new(),
            sweep: file.sweeps.clone(),
            cell: cell.to_vec(),
        };
        for (index, spec) in file.viewpoints.iter().enumerate() {
            let viewpoint = experiment
                .resolve(index, spec)
                .map_err(|e| e.context(format!("viewpoint {index}: ")))?;
            experiment.viewpoints.push(viewpoint);
        }
        Ok(experiment)
    }

    /// What a mapper may know of this experiment: the scanner's beam
    /// layout and reach, the range-error model, the map settings and the
    /// sigma-point set. Neither the scene nor any truth.
    pub fn mapper_view(&self) -> MapperView<'_> {
        MapperView {
            layouts: Layouts::Shared(&self.scanner.layout),
            range: &self.profile.range,
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
                let goal = IkTarget::LookAt {
                    position: (base_from_scene
                        * nalgebra::Point3::from(Vector3::from(target) + from * distance))
                    .coords,
                    boresight: Unit::new_normalize(base_from_scene * -from),
                };
                let options = IkOptions {
                    seed: index as u64,
                    ..IkOptions::default()
                };
                let joints = ik::solve(&self.sensor_chain, &goal, None, &options).map_err(|f| {
                    bad(format!(
                        "{request} is unreachable for robot '{}': best position error {:.4} m \
                         (orientation {:.4} rad) after {} restarts; move the target closer to the base \
                         or change `distance`/`from`",
                        self.robot.name, f.position_error, f.orientation_error, options.restarts
                    ))
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
            return Err(bad(format!(
                "{}: the sensor origin {:?} is inside object '{}'",
                viewpoint.request,
                origin.coords.as_slice(),
                self.scene.objects()[object].name
            )));
        }
        Ok(viewpoint)
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

mod file;
#[cfg(test)]
mod tests;
