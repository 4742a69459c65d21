//! The map settings an experiment may set and sweep: OctoMap's tree settings
//! (hit and miss steps, the clamp) for the ray update and for every map's
//! clamp, the cell model's bounds and risk level for the OPDF merge, and beam
//! pooling. The defaults are OctoMap's and the paper's (docs/math.md §4.2,
//! §5.4, §5.5).

use super::chord::CellModel;
use super::merge::MergeOptions;
use super::octree::{logodds, Clamp};
use super::pooling::Pooling;
use super::ray_update::UpdateRule;

/// How every map of an experiment is built.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MapSettings {
    /// OctoMap's update (hit, miss, clamp); the clamp bounds every map.
    pub update: UpdateRule,
    /// What one beam says about one cell (OPDF methods).
    pub model: CellModel,
    /// Which hits' ranges the uncertainty-aware methods pool with their
    /// neighbours on the surface they share (docs/math.md §5.5).
    pub beam_pooling: Pooling,
    /// The same for the ray update's rays and the rays `--export-rays`
    /// writes: [`MapSettings::beam_pooling`] when an experiment sets it,
    /// otherwise off (OctoMap's rays).
    pub ray_pooling: Pooling,
    /// Whether each viewpoint's grid samples the surface between
    /// neighbouring beams that lie on one plane (docs/math.md §5.4; OPDF
    /// methods).
    pub interpolate_beams: bool,
    /// Which neighbouring beams the samples join (docs/math.md §5.4).
    pub sample_gate: SampleGate,
}

/// The test that decides where surface samples join neighbouring beams: the
/// windows' χ² test at 99% on nine hits (docs/math.md §5.4, §5.5), with each
/// hit's noise as the sensor model gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleGate {
    /// Whether each hit's noise holds the sideways share of its direction
    /// noise, `r σ_a` (the model, `sample_gate = "model"`), or its range
    /// noise alone (`"range"`).
    pub direction_noise: bool,
    /// Whether a hit's noise along its beam is the sensor's range noise
    /// `σ(r)` (`"sensor"`: the measurement's own, whatever pooling and the
    /// pose error make of the beam) or the beam's σ (`"model"`, `"range"`:
    /// the pooled range's, or the propagated point's along the beam).
    pub sensor_sigma: bool,
    /// How many times each hit's noise is widened (`"model*k"`): 1 is the
    /// model; more is a tuned gate, kept to compare against.
    pub widening: f64,
}

impl Default for SampleGate {
    fn default() -> Self {
        Self {
            direction_noise: true,
            sensor_sigma: false,
            widening: 1.0,
        }
    }
}

impl SampleGate {
    /// The gate an experiment file names: `"model"` (range and direction
    /// noise), `"range"` (range noise alone), `"sensor"` (the sensor's range
    /// noise σ(r) and direction noise), one widened `k` times as `"model*k"`
    /// (1 ≤ k ≤ 100); or what to write instead.
    pub fn from_name(name: &str) -> Result<Self, String> {
        let bad = || {
            format!(
                "sample_gate = \"{name}\": use \"model\" (range and direction noise), \"range\" \
                 (range noise alone), \"sensor\" (the sensor's own range and direction noise), or \
                 one widened k times as \"model*k\" (1 <= k <= 100)"
            )
        };
        let (noise, widening) = match name.split_once('*') {
            Some((noise, k)) => (noise.trim(), k.trim().parse::<f64>().map_err(|_| bad())?),
            None => (name, 1.0),
        };
        let (direction_noise, sensor_sigma) = match noise {
            "model" => (true, false),
            "range" => (false, false),
            "sensor" => (true, true),
            _ => return Err(bad()),
        };
        if !(widening.is_finite() && (1.0..=100.0).contains(&widening)) {
            return Err(bad());
        }
        Ok(Self {
            direction_noise,
            sensor_sigma,
            widening,
        })
    }

    /// The noise the gate gives a hit at range `r` whose beam has σ `sigma`
    /// along it, for a sensor whose own range σ on that beam is
    /// `sensor_sigma()` and whose direction noise is `angular_sigma`:
    /// (along the beam, sideways).
    pub fn noise(
        &self,
        r: f64,
        sigma: f64,
        sensor_sigma: impl FnOnce() -> f64,
        angular_sigma: f64,
    ) -> (f64, f64) {
        let along = if self.sensor_sigma {
            sensor_sigma()
        } else {
            sigma
        };
        let lateral = if self.direction_noise {
            r * angular_sigma
        } else {
            0.0
        };
        (along * self.widening, lateral * self.widening)
    }
}

/// What the uncertainty-aware methods do when an experiment leaves a
/// setting out (docs/math.md §5.7): the configuration that won the paired
/// comparisons of `paper_defaults.toml` and `paper_shelf_defaults.toml`.
/// The ray update keeps OctoMap's raw rays unless `beam_pooling` is set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpdfDefaults {
    /// `beam_pooling`.
    pub beam_pooling: Pooling,
    /// `interpolate_beams`.
    pub interpolate_beams: bool,
    /// `risk`.
    pub risk: Option<f64>,
}

impl OpdfDefaults {
    /// The measured defaults.
    pub const MEASURED: Self = Self {
        beam_pooling: Pooling::Windows,
        interpolate_beams: true,
        risk: Some(0.5),
    };
}

/// The settings as probabilities, the way OctoMap's setters and the
/// experiment file's `[map]` table give them.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MapProbabilities {
    /// OctoMap's `probHit` (0.7).
    pub prob_hit: f64,
    /// OctoMap's `probMiss` (0.4).
    pub prob_miss: f64,
    /// OctoMap's `clampingThresMin` (0.1192).
    pub clamp_min: f64,
    /// OctoMap's `clampingThresMax` (0.971).
    pub clamp_max: f64,
    /// The cell model's `p_lo` (0.02): a crossed cell's probability.
    pub p_lo: f64,
    /// The cell model's `p_hi` (0.98): the most one beam may say.
    pub p_hi: f64,
}

impl Default for MapProbabilities {
    fn default() -> Self {
        Self {
            prob_hit: 0.7,
            prob_miss: 0.4,
            clamp_min: 0.1192,
            clamp_max: 0.971,
            p_lo: 0.02,
            p_hi: 0.98,
        }
    }
}

impl MapSettings {
    /// Settings from probabilities, a risk level and the pooling switch;
    /// the error names the setting that is out of range. OctoMap's values
    /// give its constants bit for bit ([`MapSettings::default`]).
    pub fn new(
        p: &MapProbabilities,
        risk: Option<f64>,
        beam_pooling: Pooling,
    ) -> Result<Self, String> {
        let open = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && v > lo && v < hi {
                Ok(())
            } else {
                Err(format!(
                    "{name} = {v} must lie strictly between {lo} and {hi}"
                ))
            }
        };
        open("map.prob_hit", p.prob_hit, 0.5, 1.0)?;
        open("map.prob_miss", p.prob_miss, 0.0, 0.5)?;
        open("map.clamp_min", p.clamp_min, 0.0, 0.5)?;
        open("map.clamp_max", p.clamp_max, 0.5, 1.0)?;
        open("map.p_lo", p.p_lo, 0.0, 0.5)?;
        open("map.p_hi", p.p_hi, 0.5, 1.0)?;
        if let Some(risk) = risk {
            if !(risk.is_finite() && (1e-9..=0.5).contains(&risk)) {
                return Err(format!(
                    "risk = {risk} must be a probability between 1e-9 and 0.5 (leave it out for none)"
                ));
            }
        }
        Ok(Self {
            update: UpdateRule {
                hit: logodds(p.prob_hit),
                miss: logodds(p.prob_miss),
                clamp: Clamp {
                    min: logodds(p.clamp_min),
                    max: logodds(p.clamp_max),
                },
            },
            model: CellModel {
                p_lo: p.p_lo,
                p_hi: p.p_hi,
                risk,
            },
            beam_pooling,
            ray_pooling: beam_pooling,
            interpolate_beams: false,
            sample_gate: SampleGate::default(),
        })
    }

    /// Every method pooled alike, as an experiment that sets
    /// `beam_pooling` has it.
    pub fn pool_every_method(&mut self, pooling: Pooling) {
        self.beam_pooling = pooling;
        self.ray_pooling = pooling;
    }

    /// The settings of the uncertainty-aware maps and of the ray update in
    /// words, as an experiment file writes them (for reports).
    pub fn describe(&self) -> (String, String) {
        let noise = match (
            self.sample_gate.sensor_sigma,
            self.sample_gate.direction_noise,
        ) {
            (true, _) => "sensor",
            (false, true) => "model",
            (false, false) => "range",
        };
        let gate = match self.sample_gate.widening {
            1.0 => noise.to_string(),
            k => format!("{noise}*{k}"),
        };
        let samples = if self.interpolate_beams {
            format!("on (gate {gate})")
        } else {
            "off".into()
        };
        let risk = self
            .model
            .risk
            .map_or_else(|| "off".to_string(), |r| format!("ε = {r}"));
        (
            format!(
                "beam pooling {}, surface samples {samples}, risk level {risk}",
                self.beam_pooling.name()
            ),
            format!("beam pooling {}", self.ray_pooling.name()),
        )
    }

    /// The OPDF merge's options: the cell model and the map's clamp.
    pub fn merge_options(&self) -> MergeOptions {
        MergeOptions {
            model: self.model,
            clamp: self.update.clamp,
        }
    }

    /// The map-level clamp.
    pub fn clamp(&self) -> Clamp {
        self.update.clamp
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vector3;
    use crate::uncertainty::RangeModel;

    #[test]
    fn octomap_probabilities_give_octomap_constants_bit_for_bit() {
        let settings = MapSettings::new(&MapProbabilities::default(), None, Pooling::Off).unwrap();
        assert_eq!(settings, MapSettings::default());
        assert_eq!(
            settings.update.hit.to_bits(),
            UpdateRule::OCTOMAP.hit.to_bits()
        );
        assert_eq!(
            settings.update.clamp.min.to_bits(),
            Clamp::OCTOMAP.min.to_bits()
        );
        assert_eq!(
            settings.update.clamp.max.to_bits(),
            Clamp::OCTOMAP.max.to_bits()
        );
        assert_eq!(settings.merge_options(), MergeOptions::default());
    }

    #[test]
    fn out_of_range_settings_name_themselves() {
        let bad = |f: fn(&mut MapProbabilities)| {
            let mut p = MapProbabilities::default();
            f(&mut p);
            MapSettings::new(&p, None, Pooling::Off).unwrap_err()
        };
        assert!(bad(|p| p.prob_hit = 0.5).starts_with("map.prob_hit = 0.5"));
        assert!(bad(|p| p.prob_miss = f64::NAN).starts_with("map.prob_miss"));
        assert!(bad(|p| p.clamp_min = 0.6).starts_with("map.clamp_min"));
        assert!(bad(|p| p.clamp_max = 1.0).starts_with("map.clamp_max"));
        assert!(bad(|p| p.p_lo = 0.0).starts_with("map.p_lo"));
        assert!(bad(|p| p.p_hi = 0.4).starts_with("map.p_hi"));
        let risk = MapSettings::new(&MapProbabilities::default(), Some(0.7), Pooling::Off);
        assert!(risk.unwrap_err().starts_with("risk = 0.7"));
    }

    #[test]
    fn sample_gates_read_their_names_and_refuse_others() {
        let gate = |name: &str| SampleGate::from_name(name);
        assert_eq!(gate("model"), Ok(SampleGate::default()));
        let range = gate("range").unwrap();
        assert!(!range.direction_noise && range.widening == 1.0);
        let widened = gate("range*6").unwrap();
        assert!(!widened.direction_noise && widened.widening == 6.0);
        let sensor = RangeModel {
            sigma0: 0.001,
            k: 0.002,
            k2: 0.0,
            angular_sigma: 0.001,
            ..RangeModel::NOISELESS
        };
        let own = || sensor.sigma(&Vector3::z(), 0.5);
        let angular = sensor.angular_sigma;
        assert_eq!(widened.noise(0.5, 0.002, own, angular), (0.012, 0.0));
        let (along, lateral) = gate("model").unwrap().noise(0.5, 0.003, own, angular);
        assert_eq!((along, lateral), (0.003, 0.0005));
        // The sensor's own σ(0.5) = 2 mm, not the beam's 3 mm.
        let (along, lateral) = gate("sensor").unwrap().noise(0.5, 0.003, own, angular);
        assert_eq!((along, lateral), (0.002, 0.0005));
        for bad in ["modle", "range*0.5", "model*", "model*nan", "range*1000"] {
            let message = gate(bad).unwrap_err();
            assert!(
                message.starts_with(&format!("sample_gate = \"{bad}\"")),
                "{message}"
            );
        }
    }
}
