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
    /// Which hits' ranges are pooled with their neighbours on the surface
    /// they share (docs/math.md §5.5; every method maps the pooled points).
    pub beam_pooling: Pooling,
    /// Whether each viewpoint's grid samples the surface between
    /// neighbouring beams that lie on one plane (docs/math.md §5.4; OPDF
    /// methods).
    pub interpolate_beams: bool,
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
            interpolate_beams: false,
        })
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
}
