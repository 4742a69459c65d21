//! Read access to a checked [`Experiment`]: its fields are private, so
//! nothing changes an experiment after `Experiment::load_with` checked it.

use super::*;

impl Experiment {
    /// Its name (the results folder is `results/<name>/`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Free text.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// The experiment file.
    pub fn source(&self) -> &Path {
        &self.source
    }

    /// The run's seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The map's finest voxel edge (m): `resolution` in the file, default 0.01.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Whether the scene sits at a sub-voxel offset drawn from each run's seed
    /// (`grid_offset = true`), so that no face lies on a cell plane by design.
    pub fn grid_offset(&self) -> bool {
        self.grid_offset
    }

    /// How maps are built: OctoMap's hit, miss and clamp (`[map]`), the
    /// cell model's bounds (`[map]`) and risk level ε (`risk`; docs/math.md
    /// §5.4), beam pooling (`beam_pooling`; §5.5), surface samples between
    /// beams (`interpolate_beams`) and their gate (`sample_gate`; §5.4).
    /// Defaults: OctoMap's and the paper's values for `[map]`, sigmap's
    /// (§5.7) for the rest.
    pub fn map(&self) -> &MapSettings {
        &self.map
    }

    /// Why the defaults' surface samples are off, if they are: the raster's
    /// beams per viewpoint, too many to sample (`check_sample_budget`).
    pub fn samples_over_budget(&self) -> Option<usize> {
        self.samples_over_budget
    }

    /// The sigma-point set of the `unscented` and `correlated` methods: the
    /// paper's, or the scaled set of an `[unscented]` table (docs/math.md
    /// §3.2).
    pub fn sigma_set(&self) -> SigmaSet {
        self.sigma_set
    }

    /// The seeds of `sigmap run` (`seeds = [..]`, default `[seed]`).
    pub fn seeds(&self) -> &[u64] {
        &self.seeds
    }

    /// The modelling methods compared by `sigmap run`: `methods` (default
    /// blind, unscented, ray_update), then the `[[mapper]]` tables.
    pub fn methods(&self) -> &[RunMethod] {
        &self.methods
    }

    /// The method every other one is paired against in `paired.csv`
    /// (`reference = ".."`; default `ray_update` when listed, else the
    /// first method).
    pub fn reference(&self) -> &RunMethod {
        &self.reference
    }

    /// Every method the others are paired against: the reference, then
    /// those of `also_paired = [..]`.
    pub fn paired_references(&self) -> impl Iterator<Item = &RunMethod> {
        std::iter::once(&self.reference).chain(&self.also_paired)
    }

    /// What the user should know of the experiment's files that is not an
    /// error, one line each (`note: …`): the scene's notes, and a pose of
    /// `[robot]` or `[world_from_scene]` turned by more than a full turn.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The workcell scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The robot.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// `base_link -> flange_link`: the arm (T_rw = world_from_base · FK).
    pub fn arm(&self) -> &KinematicChain {
        &self.arm
    }

    /// `base_link -> sensor_link`, for inverse kinematics.
    pub fn sensor_chain(&self) -> &KinematicChain {
        &self.sensor_chain
    }

    /// Nominal `robot_from_camera` (T_cr): the URDF's flange → laser joints.
    pub fn robot_from_camera(&self) -> Pose {
        self.robot_from_camera
    }

    /// Where the robot base stands in the world.
    pub fn world_from_base(&self) -> Isometry3 {
        self.world_from_base
    }

    /// Nominal `world_from_scene` (T_sw).
    pub fn world_from_scene(&self) -> Pose {
        self.world_from_scene
    }

    /// The scanner.
    pub fn scanner(&self) -> &Scanner {
        &self.scanner
    }

    /// The error profile: what the simulator draws.
    pub fn profile(&self) -> &ErrorProfile {
        &self.profile
    }

    /// What the maps are told of the profile's errors (`[believed]`).
    pub fn believed(&self) -> &BelievedErrors {
        &self.believed
    }

    /// The error profile the maps are told, before `[believed]`'s factors:
    /// the one its `profile` names (at the experiment's pose error scale),
    /// else the one the simulator draws.
    pub fn believed_profile(&self) -> &ErrorProfile {
        self.believed_profile.as_ref().unwrap_or(&self.profile)
    }

    /// How the reference `registration_belief` is drawn and called
    /// (`[registration_belief]`).
    pub fn registration_belief(&self) -> BeliefSettings {
        self.registration_belief
    }

    /// The scene registration as the maps are told it: nominal T_sw with the
    /// believed profile's covariance times `[believed] pose_sigma²`, what
    /// every scan states and `registration_belief` draws from.
    pub fn told_world_from_scene(&self) -> crate::uncertainty::UncertainPose {
        crate::uncertainty::UncertainPose {
            mean: self.world_from_scene,
            covariance: self.believed_profile().world_from_scene * self.believed.pose_variance(),
        }
    }

    /// The viewpoints, resolved to joint configurations.
    pub fn viewpoints(&self) -> &[Viewpoint] {
        &self.viewpoints
    }

    /// The sweep axes (runs are their cartesian product times the seeds).
    pub fn sweep(&self) -> &[SweepAxis] {
        &self.sweep
    }

    /// The sweep values this experiment was loaded with (empty: the base).
    pub fn cell(&self) -> &[(String, SweepValue)] {
        &self.cell
    }
}

/// In-place changes for the crate's own tests (the library never changes a
/// checked experiment; users go through [`super::Overrides`]).
#[cfg(test)]
impl Experiment {
    pub(crate) fn map_mut(&mut self) -> &mut MapSettings {
        &mut self.map
    }

    pub(crate) fn profile_mut(&mut self) -> &mut ErrorProfile {
        &mut self.profile
    }

    pub(crate) fn sigma_set_mut(&mut self) -> &mut SigmaSet {
        &mut self.sigma_set
    }

    pub(crate) fn name_mut(&mut self) -> &mut String {
        &mut self.name
    }
}
