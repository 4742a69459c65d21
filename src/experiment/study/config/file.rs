//! The experiment file as written: the TOML schema that `Experiment::load`
//! reads and checks (unknown keys are errors).

use super::SweepAxis;
use crate::mapping::pooling::Pooling;
use crate::mapping::settings::MapProbabilities;
use crate::sim::sensor::ScannerSpec;
use serde::Deserialize;
use std::path::PathBuf;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ExperimentFile {
    pub(super) name: Option<String>,
    #[serde(default)]
    pub(super) description: String,
    pub(super) scene: PathBuf,
    pub(super) error_profile: PathBuf,
    #[serde(default = "default_seed")]
    pub(super) seed: u64,
    #[serde(default = "default_resolution")]
    pub(super) resolution: f64,
    pub(super) risk: Option<RiskSpec>,
    #[serde(default)]
    pub(super) grid_offset: bool,
    pub(super) beam_pooling: Option<PoolingSpec>,
    pub(super) interpolate_beams: Option<SwitchSpec>,
    /// The samples' gate: `"model"` (default), `"range"`, or `"model*k"`.
    #[serde(default = "default_sample_gate")]
    pub(super) sample_gate: String,
    /// `[map]`: each setting may be swept as `experiment.map.<name>` once set.
    #[serde(default)]
    pub(super) map: MapProbabilities,
    /// `[believed]`: what the maps are told of the profile's errors.
    #[serde(default)]
    pub(super) believed: crate::sim::believed::BelievedErrors,
    /// `[registration_belief]`: how the reference `registration_belief` is
    /// drawn and called.
    #[serde(default)]
    pub(super) registration_belief: crate::experiment::run::registration_belief::BeliefSettings,
    /// `[unscented]`: the scaled sigma-point set instead of the paper's.
    pub(super) unscented: Option<ScaledSetSpec>,
    pub(super) seeds: Option<SeedsSpec>,
    pub(super) methods: Option<Vec<String>>,
    /// The method the others are paired against (`paired.csv`).
    pub(super) reference: Option<String>,
    /// Further methods the others are also paired against.
    #[serde(default)]
    pub(super) also_paired: Vec<String>,
    pub(super) robot: MountSpec,
    #[serde(default)]
    pub(super) world_from_scene: PoseSpec,
    pub(super) sensor: ScannerSpec,
    #[serde(rename = "viewpoint", default)]
    pub(super) viewpoints: Vec<ViewpointSpec>,
    #[serde(rename = "sweep", default)]
    pub(super) sweeps: Vec<SweepAxis>,
    /// External mappers, run beside `methods`.
    #[serde(rename = "mapper", default)]
    pub(super) mappers: Vec<crate::experiment::run::external::MapperSpec>,
}

/// `beam_pooling` as written: `true` / `false`, or a mode's name (a string,
/// so that a sweep can take the modes: `"off"`, `"faces"`, `"windows"`).
#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "beam_pooling: true, false, \"windows\", \"faces\" or \"off\""
)]
pub(super) enum PoolingSpec {
    Switch(bool),
    Named(String),
}

impl PoolingSpec {
    /// The mode, or what to write instead.
    pub(super) fn pooling(&self) -> std::result::Result<Pooling, String> {
        match self {
            PoolingSpec::Switch(false) => Ok(Pooling::Off),
            PoolingSpec::Switch(true) => Ok(Pooling::Windows),
            PoolingSpec::Named(name) => Pooling::from_name(name).ok_or_else(|| {
                format!(
                    "beam_pooling = \"{name}\": use \"faces\" (large planar faces only), \"windows\" \
                     or true (every beam's window and the faces), or \"off\" or false"
                )
            }),
        }
    }
}

/// `seeds` as written: a list (`[1, 2, 3]`) or an inclusive range
/// (`"1..40"`, also written `"1..=40"`: forty seeds).
#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "seeds: a list of whole numbers (seeds = [1, 2, 3]) or an inclusive range (seeds = \"1..40\")"
)]
pub(super) enum SeedsSpec {
    List(Vec<u64>),
    Range(String),
}

impl SeedsSpec {
    /// The seeds, or what to write instead; a range of more than `most`
    /// seeds is refused before it is made.
    pub(super) fn seeds(&self, most: u64) -> std::result::Result<Vec<u64>, String> {
        let text = match self {
            SeedsSpec::List(seeds) => return Ok(seeds.clone()),
            SeedsSpec::Range(text) => text,
        };
        let usage = || {
            format!(
                "seeds = \"{text}\": write a list (seeds = [1, 2, 3]) or an inclusive range of \
                 whole numbers (seeds = \"1..40\" is the forty seeds 1 to 40)"
            )
        };
        let (first, last) = text.split_once("..").ok_or_else(usage)?;
        let last = last.strip_prefix('=').unwrap_or(last);
        let first: u64 = first.trim().parse().map_err(|_| usage())?;
        let last: u64 = last.trim().parse().map_err(|_| usage())?;
        if last < first {
            return Err(format!(
                "seeds = \"{text}\": the range is empty (its last seed {last} is below its first {first})"
            ));
        }
        if last - first >= most {
            return Err(format!(
                "seeds = \"{text}\" is {} seeds; sigmap runs at most {most} seeds per experiment",
                u128::from(last - first) + 1
            ));
        }
        Ok((first..=last).collect())
    }
}

/// `risk` as written: a level ε, or `"off"` (a string, so that a sweep can
/// take both).
#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "risk: a probability between 1e-9 and 0.5, or \"off\""
)]
pub(super) enum RiskSpec {
    Level(f64),
    Named(String),
}

impl RiskSpec {
    /// The level (`None`: off), or what to write instead.
    pub(super) fn level(&self) -> std::result::Result<Option<f64>, String> {
        match self {
            RiskSpec::Level(level) => Ok(Some(*level)),
            RiskSpec::Named(word) if word == "off" => Ok(None),
            RiskSpec::Named(word) => Err(format!(
                "risk = \"{word}\": use a probability between 1e-9 and 0.5, or \"off\""
            )),
        }
    }
}

/// A switch as written: `true` / `false`, or `"on"` / `"off"` (a string, so
/// that a sweep can take both).
#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "interpolate_beams: true or \"on\", false or \"off\""
)]
pub(super) enum SwitchSpec {
    Switch(bool),
    Named(String),
}

impl SwitchSpec {
    /// Whether it is on, or what to write instead (`name`: the setting).
    pub(super) fn on(&self, name: &str) -> std::result::Result<bool, String> {
        match self {
            SwitchSpec::Switch(on) => Ok(*on),
            SwitchSpec::Named(word) => match word.as_str() {
                "on" => Ok(true),
                "off" => Ok(false),
                _ => Err(format!(
                    "{name} = \"{word}\": use true or \"on\", false or \"off\""
                )),
            },
        }
    }
}

fn default_sample_gate() -> String {
    "model".into()
}

fn default_seed() -> u64 {
    1
}

fn default_resolution() -> f64 {
    0.01
}

fn default_base_link() -> String {
    "base_link".into()
}

fn default_sensor_link() -> String {
    "laser".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MountSpec {
    pub(super) urdf: PathBuf,
    #[serde(default = "default_base_link")]
    pub(super) base_link: String,
    pub(super) flange_link: String,
    #[serde(default = "default_sensor_link")]
    pub(super) sensor_link: String,
    #[serde(default)]
    pub(super) xyz: [f64; 3],
    #[serde(default)]
    pub(super) rpy: [f64; 3],
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct PoseSpec {
    #[serde(default)]
    pub(super) xyz: [f64; 3],
    #[serde(default)]
    pub(super) rpy: [f64; 3],
}

/// `[unscented]`: the Wan–van der Merwe scaled set (docs/math.md §3.2) for
/// the `unscented` and `correlated` methods.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ScaledSetSpec {
    pub(super) alpha: f64,
    #[serde(default = "default_beta")]
    pub(super) beta: f64,
    #[serde(default)]
    pub(super) kappa: f64,
}

fn default_beta() -> f64 {
    crate::uncertainty::unscented::DEFAULT_BETA
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ViewpointSpec {
    pub(super) joints: Option<Vec<f64>>,
    pub(super) look_at: Option<[f64; 3]>,
    pub(super) distance: Option<f64>,
    pub(super) from: Option<[f64; 3]>,
}
