//! Loading an experiment, step by step: the sweep cell's values, the
//! files it names, and every check, so that an [`Experiment`] that exists
//! is one that was checked ([`Experiment::load_with`]).

use super::file::{ExperimentFile, MountSpec};
use super::*;
use crate::mapping::pooling::Pooling;
use crate::mapping::settings::{OpdfDefaults, SampleGate};
use crate::mapping::Method;
use crate::sim::robot::KinematicChain;
use crate::uncertainty::RangeAxis;

/// A sweep cell's values, by the file they change (experiment, profile,
/// scene), and its pose-error scale.
struct SweptValues {
    by_file: [Vec<(String, toml::Value)>; 3],
    pose_scale: Option<f64>,
}

impl SweptValues {
    /// Sorts `cell`'s values by file; errors name the experiment file.
    fn of(path: &Path, cell: &[(String, SweepValue)]) -> Result<Self> {
        let mut out = Self {
            by_file: Default::default(),
            pose_scale: None,
        };
        let bad = |msg: String| Error::input(path, msg);
        for (field, value) in cell {
            if let SweepValue::Number(v) = value {
                if !v.is_finite() {
                    return Err(bad(format!(
                        "sweep field '{field}': value {v} is not finite"
                    )));
                }
            }
            let target = [("experiment.", 0), ("profile.", 1), ("scene.", 2)]
                .iter()
                .find_map(|(prefix, i)| field.strip_prefix(prefix).map(|rest| (*i, rest)));
            match (field.as_str(), target) {
                ("pose_error_scale", _) => match value {
                    SweepValue::Number(v) if *v >= 0.0 => out.pose_scale = Some(*v),
                    _ => {
                        return Err(bad(format!(
                            "pose_error_scale = {value} must be a number >= 0"
                        )))
                    }
                },
                (_, Some((i, rest))) => out.by_file[i].push((rest.to_string(), value.to_toml())),
                _ => {
                    return Err(bad(format!(
                        "unknown sweep field '{field}' (use pose_error_scale, experiment.<path>, \
                         profile.<path> or scene.<path>)"
                    )))
                }
            }
        }
        Ok(out)
    }

    /// The error profile at `path` with the cell's values and pose scale,
    /// its pose errors checked.
    fn profile(&self, path: &Path) -> Result<ErrorProfile> {
        self.scaled_profile(ErrorProfile::load_with(path, &self.by_file[1])?)
    }

    /// The believed profile at `path` (`[believed] profile`): at the cell's
    /// pose scale, which scales the robot's errors and so what a calibrated
    /// robot believes of them; the cell's `profile.<path>` values are the
    /// drawn profile's alone.
    fn believed_profile(&self, path: &Path) -> Result<ErrorProfile> {
        self.scaled_profile(ErrorProfile::load_with(path, &[])?)
    }

    /// `profile` at the cell's pose scale, its pose errors checked.
    fn scaled_profile(&self, mut profile: ErrorProfile) -> Result<ErrorProfile> {
        if let Some(scale) = self.pose_scale {
            profile.scale_pose_errors(scale);
        }
        let what = match self.pose_scale {
            Some(scale) => format!("at pose_error_scale = {scale:e}"),
            None => "the profile".into(),
        };
        profile
            .check_pose_magnitudes(&what)
            .map_err(|e| Error::input(&profile.source, e))?;
        Ok(profile)
    }
}

/// The file the experiment at `path` names with `key = value`, relative to
/// the experiment's folder; one that does not exist is an error naming the
/// experiment, the key and where it was looked for.
fn referred(path: &Path, key: &str, value: &Path) -> Result<PathBuf> {
    let resolved = path.parent().unwrap_or(Path::new(".")).join(value);
    if resolved.exists() {
        return Ok(resolved);
    }
    Err(Error::input(
        path,
        format!(
            "{key} = \"{}\": no such file (looked for {}; paths are relative to the experiment \
             file)",
            value.display(),
            resolved.display()
        ),
    ))
}

/// The further references of `also_paired = [..]`: each one of `methods`,
/// not the file's reference, none twice. With the methods overridden
/// (`sigmap map --method`) those no longer among them are dropped, and so
/// is the one the override made the reference (the file's reference is gone,
/// and the one method left is paired with nothing).
fn also_paired(
    names: &[String],
    (named, reference): (Option<&str>, &RunMethod),
    methods: &[RunMethod],
    overrides: &Overrides,
) -> std::result::Result<Vec<RunMethod>, String> {
    if let Some(name) = first_repeat(names) {
        return Err(format!("also_paired lists {name} more than once"));
    }
    let overridden = overrides.methods.is_some();
    let mut out = Vec::new();
    for name in names {
        if Some(name.as_str()) == named || (!overridden && name == reference.as_str()) {
            return Err(format!(
                "also_paired lists {name}, which is already the reference"
            ));
        }
        if name == reference.as_str() {
            continue;
        }
        match methods.iter().find(|m| m.as_str() == name) {
            Some(method) => out.push(method.clone()),
            None if overridden => {}
            None => {
                let listed: Vec<&str> = methods.iter().map(RunMethod::as_str).collect();
                return Err(format!(
                    "also_paired lists {name}, which is not one of `methods` or the [[mapper]] \
                     tables ({})",
                    listed.join(", ")
                ));
            }
        }
    }
    Ok(out)
}

/// Every sweep axis has values, none twice, no field is swept twice, and a
/// reference value is one of its axis's values.
fn check_sweep_axes(sweeps: &[SweepAxis]) -> std::result::Result<(), String> {
    for (i, axis) in sweeps.iter().enumerate() {
        if axis.values.is_empty() {
            return Err(format!("[[sweep]] '{}' has no values", axis.field));
        }
        if sweeps[..i].iter().any(|a| a.field == axis.field) {
            return Err(format!("[[sweep]] '{}' is swept twice", axis.field));
        }
        let labels: Vec<String> = axis.values.iter().map(ToString::to_string).collect();
        if let Some(label) = first_repeat(&labels) {
            return Err(format!(
                "[[sweep]] '{}' lists the value {label} more than once",
                axis.field
            ));
        }
        if let Some(reference) = &axis.reference {
            if !axis.values.contains(reference) {
                return Err(format!(
                    "[[sweep]] '{}': reference = {reference} is not one of its values ({})",
                    axis.field,
                    labels.join(", ")
                ));
            }
        }
    }
    Ok(())
}

/// How the robot carries the sensor and stands in the world, with the
/// scene: the arm and sensor chains, T_cr, the base and T_sw.
struct Mount {
    arm: KinematicChain,
    sensor_chain: KinematicChain,
    robot_from_camera: Pose,
    world_from_base: Isometry3,
    world_from_scene: Pose,
}

impl Mount {
    /// The mount of `robot` as the file's `[robot]` and `[world_from_scene]`
    /// say; a joint error per joint must match the arm's joints.
    fn of(
        robot: &Robot,
        mount: &MountSpec,
        file: &ExperimentFile,
        profile: &ErrorProfile,
        path: &Path,
    ) -> Result<Self> {
        let bad = |msg: String| Error::input(path, msg);
        let arm = robot.chain(&mount.base_link, &mount.flange_link)?;
        let sensor_chain = robot.chain(&mount.base_link, &mount.sensor_link)?;
        let mount_chain = robot.chain(&mount.flange_link, &mount.sensor_link)?;
        if mount_chain.dof() != 0 {
            return Err(bad(format!(
                "[robot] the joints between '{}' and '{}' must all be fixed: they are the \
                 sensor mount T_cr",
                mount.flange_link, mount.sensor_link
            )));
        }
        check_joint_errors(profile, robot, &arm)?;
        let base = Pose::new(mount.xyz, mount.rpy);
        let world_from_scene = Pose::new(file.world_from_scene.xyz, file.world_from_scene.rpy);
        if !base.is_finite() || !world_from_scene.is_finite() {
            return Err(bad(
                "[robot] and [world_from_scene] poses must be finite".into()
            ));
        }
        Ok(Self {
            robot_from_camera: Pose::from_isometry(&mount_chain.forward_unchecked(&[])),
            arm,
            sensor_chain,
            world_from_base: base.to_isometry(),
            world_from_scene,
        })
    }
}

/// The `[believed]` table of the experiment at `path` whose drawn profile
/// is `profile` (read from `profile_path`), checked, with the profile it
/// names loaded at the cell's pose scale (`None`: the drawn profile's
/// errors, also when it names the drawn profile's file).
fn believed_of(
    table: &BelievedErrors,
    (path, profile, profile_path): (&Path, &ErrorProfile, &Path),
    swept: &SweptValues,
    (robot, arm, scanner): (&Robot, &KinematicChain, &Scanner),
) -> Result<(BelievedErrors, Option<ErrorProfile>)> {
    let mut believed = table.clone();
    let told_path = match &believed.profile {
        Some(told) => Some(referred(path, "[believed] profile", told)?),
        None => None,
    };
    // The drawn profile named again is the calibrated belief (with the
    // cell's `profile.<path>` values).
    if told_path
        .as_ref()
        .is_some_and(|told| same_file(told, profile_path))
    {
        believed.profile = None;
    }
    let told = match told_path.filter(|_| believed.profile.is_some()) {
        Some(told) => {
            let told = swept.believed_profile(&told)?;
            check_joint_errors(&told, robot, arm)?;
            check_range_axis(&told, scanner)
                .map_err(|e| Error::input(path, format!("[believed] profile: {e}")))?;
            Some(told)
        }
        None => None,
    };
    believed
        .check(told.as_ref().unwrap_or(profile))
        .map_err(|e| Error::input(path, e))?;
    Ok((believed, told))
}

/// Whether `a` and `b` name the same file (by their canonical paths).
fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// A joint error per joint of `profile` must match `arm`'s joints; the
/// error names the profile.
fn check_joint_errors(profile: &ErrorProfile, robot: &Robot, arm: &KinematicChain) -> Result<()> {
    match &profile.arm {
        crate::sim::profile::ArmError::Joints(s) if s.len() != arm.dof() => Err(Error::input(
            &profile.source,
            format!(
                "[world_from_robot] joint_sigma has {} values, the arm '{}' has {} joints",
                s.len(),
                robot.name,
                arm.dof()
            ),
        )),
        _ => Ok(()),
    }
}

/// The map settings of the file with the overrides applied; what neither
/// sets is the uncertainty-aware methods' default ([`OpdfDefaults`]), and
/// the ray update then maps OctoMap's raw rays. The defaults' surface
/// samples stay off for a raster of `beams` per viewpoint too dense to
/// sample, and that count is returned with the settings; asked for there,
/// the samples are refused later (`checked_scanner`).
fn map_settings(
    file: &ExperimentFile,
    overrides: &Overrides,
    beams: usize,
) -> std::result::Result<(MapSettings, Option<usize>), String> {
    let defaults = OpdfDefaults::MEASURED;
    let pooling = match (overrides.beam_pooling, &file.beam_pooling) {
        (Some(pooling), _) => Some(pooling),
        (None, Some(spec)) => Some(spec.pooling()?),
        (None, None) => None,
    };
    let risk = match (overrides.risk, &file.risk) {
        (Some(risk), _) => risk,
        (None, Some(spec)) => spec.level()?,
        (None, None) => defaults.risk,
    };
    let mut map = MapSettings::new(&file.map, risk, pooling.unwrap_or(defaults.beam_pooling))?;
    map.ray_pooling = pooling.unwrap_or(Pooling::Off);
    let mut over_budget = None;
    map.interpolate_beams = match (overrides.interpolate_beams, &file.interpolate_beams) {
        (Some(on), _) => on,
        (None, Some(spec)) => spec.on("interpolate_beams")?,
        (None, None) if defaults.interpolate_beams => {
            over_budget = check_sample_budget(beams as f64).err().map(|_| beams);
            over_budget.is_none()
        }
        (None, None) => false,
    };
    map.sample_gate = SampleGate::from_name(&file.sample_gate)?;
    Ok((map, over_budget))
}

/// The seeds of `sigmap run`: at most [`MAX_SEEDS`], none twice.
fn seeds_of(file: &ExperimentFile, seed: u64) -> std::result::Result<Vec<u64>, String> {
    let seeds = match &file.seeds {
        Some(spec) => spec.seeds(MAX_SEEDS as u64)?,
        None => vec![seed],
    };
    if seeds.len() > MAX_SEEDS {
        return Err(format!(
            "`seeds` lists {} seeds; sigmap runs at most {MAX_SEEDS} seeds per experiment",
            seeds.len()
        ));
    }
    if seeds.is_empty() {
        return Err("`seeds` is empty".into());
    }
    if let Some(seed) = first_repeat(&seeds) {
        return Err(format!("`seeds` lists {seed} more than once"));
    }
    Ok(seeds)
}

/// sigmap's own methods (the overrides', else the file's, else blind,
/// unscented and ray update), none twice. The file's list is read even when
/// overridden (`sigmap map --method`): a name in it that is no method is
/// the file's error whatever the command.
fn own_methods(
    file: &ExperimentFile,
    overrides: &Overrides,
) -> std::result::Result<Vec<Method>, String> {
    let listed: Option<Vec<Method>> = file
        .methods
        .as_ref()
        .map(|names| names.iter().map(|n| n.parse()).collect())
        .transpose()?;
    let methods = match (&overrides.methods, listed) {
        (Some(methods), _) => methods.clone(),
        (None, None) => vec![Method::Blind, Method::Unscented, Method::RayUpdate],
        (None, Some(listed)) => listed,
    };
    if methods.is_empty() {
        return Err("`methods` is empty".into());
    }
    if let Some(method) = first_repeat(&methods) {
        return Err(format!("`methods` lists {method} more than once"));
    }
    Ok(methods)
}

/// `own` then the file's `[[mapper]]` tables (their programs relative to
/// `folder`), each name new; the depth images' placeholders only with a
/// depth camera (`camera`).
fn with_mappers(
    own: &[Method],
    mappers: Vec<crate::experiment::run::external::MapperSpec>,
    folder: &Path,
    camera: bool,
) -> std::result::Result<Vec<RunMethod>, String> {
    let mut methods: Vec<RunMethod> = own.iter().copied().map(RunMethod::Own).collect();
    for spec in mappers {
        let taken: Vec<&str> = Method::ALL
            .iter()
            .map(|m| m.as_str())
            .chain(methods.iter().map(RunMethod::as_str))
            .collect();
        let mapper = spec.check(folder, &taken, camera)?;
        methods.push(RunMethod::External(std::sync::Arc::new(mapper)));
    }
    Ok(methods)
}

/// Refuses a depth camera's error (`[range] along = "depth"`) on a sensor
/// that is not one, or on beams too far off its optical axis.
fn check_range_axis(profile: &ErrorProfile, scanner: &Scanner) -> std::result::Result<(), String> {
    if profile.range.along == RangeAxis::Depth && scanner.camera.is_none() {
        return Err(format!(
            "the profile {} gives a depth camera's error ([range] along = \"depth\") and [sensor] \
             is a laser scanner's raster: give [sensor] model = \"pinhole\", or a profile whose \
             range error is along the ray",
            profile.source.display()
        ));
    }
    profile
        .range
        .check_directions(scanner.directions())
        .map_err(|e| format!("[sensor]: {e}"))
}

/// The file's scanner, checked against the viewpoints' beam budget, the
/// sample budget and (for methods that build grids) the clearing bound at
/// `resolution`.
fn checked_scanner(
    file: &ExperimentFile,
    scanner: Scanner,
    map: &MapSettings,
    builds_grids: bool,
    resolution: f64,
) -> std::result::Result<Scanner, String> {
    let viewpoints = file.viewpoints.len();
    if viewpoints == 0 {
        return Err("the experiment has no [[viewpoint]]".into());
    }
    let per_viewpoint = scanner.directions().len();
    let beams = per_viewpoint as f64 * viewpoints as f64;
    if viewpoints > MAX_VIEWPOINTS || beams > MAX_BEAMS_PER_RUN {
        return Err(format!(
            "{viewpoints} viewpoints x {per_viewpoint} beams = {beams:.3e} beams per run; sigmap \
             handles at most {MAX_VIEWPOINTS} viewpoints and {MAX_BEAMS_PER_RUN:.0} beams per run \
             (use fewer viewpoints or larger sensor steps)"
        ));
    }
    if map.interpolate_beams {
        check_sample_budget(per_viewpoint as f64)?;
    }
    if builds_grids {
        scanner.check_clearing(resolution)?;
    }
    Ok(scanner)
}

impl Experiment {
    /// Reads the experiment with one sweep cell's values and `overrides`
    /// applied, and checks everything: the values an override gives are
    /// checked as the file's. Every error names its file.
    pub fn load_with(
        path: &Path,
        cell: &[(String, SweepValue)],
        overrides: &Overrides,
    ) -> Result<Self> {
        let swept = SweptValues::of(path, cell)?;
        let file: ExperimentFile = read_toml_with(path, &swept.by_file[0])?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let bad = |msg: String| Error::input(path, msg);
        let scene_path = referred(path, "scene", &file.scene)?;
        let scene = Scene::load_with(&scene_path, &swept.by_file[2])?;
        let profile_path = referred(path, "error_profile", &file.error_profile)?;
        let profile = swept.profile(&profile_path)?;
        check_sweep_axes(&file.sweeps).map_err(&bad)?;
        let robot = Robot::load(&referred(path, "[robot] urdf", &file.robot.urdf)?)?;
        let mount = Mount::of(&robot, &file.robot, &file, &profile, path)?;
        let mut notes = scene.notes().to_vec();
        notes.extend_from_slice(robot.notes());
        let written = [
            ("[robot]", Pose::new(file.robot.xyz, file.robot.rpy)),
            ("[world_from_scene]", mount.world_from_scene),
        ];
        for (table, pose) in written {
            notes.extend(pose.degrees_note(&format!("{} {table}:", path.display())));
        }
        let resolution = overrides.resolution.unwrap_or(file.resolution);
        if !crate::mapping::octree::RESOLUTIONS.contains(&resolution) {
            return Err(bad(format!(
                "resolution = {resolution} must be between 0.001 and 1 m"
            )));
        }
        let scanner = file.sensor.build().map_err(&bad)?;
        check_range_axis(&profile, &scanner).map_err(&bad)?;
        let (believed, believed_profile) = believed_of(
            &file.believed,
            (path, &profile, &profile_path),
            &swept,
            (&robot, &mount.arm, &scanner),
        )?;
        let (map, samples_over_budget) =
            map_settings(&file, overrides, scanner.directions().len()).map_err(&bad)?;
        let registration_belief = file.registration_belief.checked().map_err(&bad)?;
        let sigma_set = match &file.unscented {
            Some(spec) => SigmaSet::scaled(spec.alpha, spec.beta, spec.kappa)
                .map_err(|e| bad(format!("[unscented] {e}")))?,
            None => SigmaSet::Paper,
        };
        let seed = overrides.seed.unwrap_or(file.seed);
        let seeds = seeds_of(&file, seed).map_err(&bad)?;
        let own = own_methods(&file, overrides).map_err(&bad)?;
        let builds_grids = own.iter().any(|m| m.builds_grids());
        let scanner =
            checked_scanner(&file, scanner, &map, builds_grids, resolution).map_err(&bad)?;
        scene.check_resolution(resolution)?;
        let camera = scanner.camera.is_some();
        let methods = with_mappers(&own, file.mappers, dir, camera).map_err(&bad)?;
        // With the methods overridden (`sigmap map --method`) the file's
        // reference counts only if it is still among them.
        let named = file.reference.as_deref().filter(|name| {
            overrides.methods.is_none() || methods.iter().any(|m| m.as_str() == *name)
        });
        let reference = reference_method(named, &methods).map_err(&bad)?;
        let also_paired = also_paired(
            &file.also_paired,
            (file.reference.as_deref(), &reference),
            &methods,
            overrides,
        )
        .map_err(&bad)?;
        let mut experiment = Self {
            name: file.name.unwrap_or_else(|| crate::files::stem(path)),
            description: file.description,
            source: path.to_path_buf(),
            seed,
            resolution,
            grid_offset: overrides.grid_offset.unwrap_or(file.grid_offset),
            map,
            samples_over_budget,
            sigma_set,
            seeds,
            methods,
            reference,
            also_paired,
            scene,
            robot,
            arm: mount.arm,
            sensor_chain: mount.sensor_chain,
            robot_from_camera: mount.robot_from_camera,
            world_from_base: mount.world_from_base,
            world_from_scene: mount.world_from_scene,
            scanner,
            believed,
            believed_profile,
            registration_belief,
            profile,
            viewpoints: Vec::new(),
            sweep: file.sweeps,
            cell: cell.to_vec(),
            notes,
        };
        for (index, spec) in file.viewpoints.iter().enumerate() {
            let viewpoint = experiment
                .resolve(index, spec)
                .map_err(|e| e.context(format!("viewpoint {index}: ")))?;
            experiment.viewpoints.push(viewpoint);
        }
        Ok(experiment)
    }
}
