//! What a map that knows the scene registration's covariance, and nothing
//! else wrong, would believe (docs/math.md §7.5): the reference method
//! `registration_belief`.
//!
//! The registered truth (`runner::registered_truth`) is the scene where the
//! run's registration draw puts it. A map that cannot estimate that draw,
//! however good its sensor and arm, can believe no more than the scene
//! blurred over the registration's covariance as the maps are told it
//! (`[believed]`). `registration_belief` draws that covariance `draws`
//! times around the run's registration and calls a cell occupied where more
//! than a fraction `threshold` of the draws put a solid in it, free
//! otherwise: a perfect sensor on a perfect arm, deciding at `threshold`.
//! Scored beside the registered truth, it places the target bounds on an
//! ideal map's own trade-off between precision and the false-free rate.

use super::runner::registered_placement;
use crate::eval::ground_truth::{voxelise_votes, KeyBox};
use crate::experiment::{Experiment, RunTruth};
use crate::geometry::Vector3;
use crate::mapping::octree::Octree;
use crate::sim::streams::{Stream, Streams};
use crate::sim::truth::draw_pose;
use serde::Deserialize;

/// The most draws a belief takes: each costs about one voxelisation of the
/// scored region's surfaces.
pub const MAX_DRAWS: usize = 1024;

/// `[registration_belief]`: how the belief is drawn and called.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BeliefSettings {
    /// A cell is occupied where more than this fraction of the draws put a
    /// solid in it (0.5: where the draws are more likely than not to).
    #[serde(default = "default_threshold")]
    pub threshold: f64,
    /// Registration errors drawn per run.
    #[serde(default = "default_draws")]
    pub draws: usize,
}

fn default_threshold() -> f64 {
    0.5
}

fn default_draws() -> usize {
    32
}

impl Default for BeliefSettings {
    fn default() -> Self {
        Self {
            threshold: default_threshold(),
            draws: default_draws(),
        }
    }
}

impl BeliefSettings {
    /// The settings, or what to write instead.
    pub fn checked(self) -> std::result::Result<Self, String> {
        if !(self.threshold > 0.0 && self.threshold < 1.0) {
            return Err(format!(
                "[registration_belief] threshold = {}: give a fraction of the draws strictly \
                 between 0 and 1 (0.5: occupied where most draws put a solid)",
                self.threshold
            ));
        }
        if !(1..=MAX_DRAWS).contains(&self.draws) {
            return Err(format!(
                "[registration_belief] draws = {}: give between 1 and {MAX_DRAWS} draws (32 \
                 resolve the fraction to 1/32)",
                self.draws
            ));
        }
        Ok(self)
    }

    /// The fewest draws that call a cell occupied: more than `threshold` of
    /// them.
    pub fn votes_needed(&self) -> usize {
        (self.threshold * self.draws as f64).floor() as usize + 1
    }
}

/// The belief of the run with `seed` over the finest cells of `region`:
/// the cells [`registered_truth`] knows, each occupied where more than the
/// settings' threshold of the draws `registered · T̂_sw⁻¹ T_sw,k` (T_sw,k
/// drawn from the told registration covariance, one stream per run) put a
/// solid in it.
///
/// [`registered_truth`]: super::runner::registered_truth
pub fn registration_belief(
    experiment: &Experiment,
    truth: &RunTruth,
    seed: u64,
    offset: &Vector3,
    region: &KeyBox,
) -> Octree {
    let settings = experiment.registration_belief();
    let registered = registered_placement(experiment, truth, offset);
    let told = experiment.told_world_from_scene();
    let nominal = told.mean;
    let mut rng = Streams::new(seed).rng(Stream::RegistrationBelief);
    let draws: Vec<_> = (0..settings.draws)
        .map(|_| {
            registered * nominal.to_isometry().inverse() * draw_pose(&told, &mut rng).to_isometry()
        })
        .collect();
    voxelise_votes(
        experiment.scene(),
        experiment.resolution(),
        &registered,
        &draws,
        settings.votes_needed(),
        region,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::run::runner::{quickstart_with_profile, registered_truth};
    use crate::experiment::simulate;
    use crate::geometry::Point3;
    use crate::mapping::octomap_io::is_occupied;
    use crate::mapping::octree::DEPTH;

    /// A registration error along z alone (σ = 1.5 cm drawn), the sensor
    /// nearly exact, the maps told `told` times the drawn σ.
    fn along_z(dir: &std::path::Path, told: f64, belief: &str) -> Experiment {
        quickstart_with_profile(
            dir,
            "[range]\nsigma0 = 0.001\nk = 0.0\nangular_sigma = 0.0\ndropout = 0.0\n\
             [world_from_scene]\nsigma = [0.0, 0.0, 0.015, 0.0, 0.0, 0.0]\n",
            &format!("believed = {{ pose_sigma = {told} }}\nregistration_belief = {{ {belief} }}"),
        )
    }

    #[test]
    fn the_belief_moves_the_table_top_by_the_told_registration_error() {
        // The table top (scene z = 0.003) where the run's registration puts
        // it, z_top; each draw moves it by δ ~ N(0, σ²), σ the told 4.5 cm. A
        // cell whose bottom lies h above z_top is occupied by a draw when
        // δ > h, so with probability 1 − Φ(h/σ). At τ = Φ(−1) = 0.1587 the
        // belief is occupied where that exceeds τ: h < σ. With 400 draws the
        // fraction's standard deviation is at most 0.021: cells with h below
        // 0.7σ (probability 0.242, 4 sd above τ) are occupied and those above
        // 1.4σ (0.081, 5.7 sd below) free. At τ = Φ(1) = 0.8413 the top
        // sinks as much: the cells above −0.7σ are free. A map told the
        // drawn 1.5 cm would free the cells 1.5–3.15 cm above the top.
        let sigma = 0.045;
        for (tau, occupied_below, free_above) in [
            (0.1587, 0.7 * sigma, 1.4 * sigma),
            (0.8413, f64::NEG_INFINITY, -0.7 * sigma),
        ] {
            let dir = tempfile::tempdir().unwrap();
            let experiment = along_z(dir.path(), 3.0, &format!("threshold = {tau}, draws = 400"));
            let seed = 4;
            let run = simulate(&experiment, seed, |_| {}).unwrap();
            let offset = experiment.map_offset(seed);
            let region = KeyBox::ALL;
            let belief = registration_belief(&experiment, &run.truth, seed, &offset, &region);
            let registered = registered_placement(&experiment, &run.truth, &offset);
            let (mut occupied, mut free) = (0, 0);
            for (x, y) in [(0.3, 0.3), (-0.3, 0.3), (0.3, -0.3), (-0.32, -0.33)] {
                let top = registered * Point3::new(x, y, 0.003);
                for step in -3..10 {
                    let at = top + Vector3::z() * (0.01 * step as f64);
                    let key = belief.key(&at).unwrap();
                    let h = belief.center(&key, DEPTH).z - 0.005 - top.z;
                    let call = belief.query(&key, DEPTH).map(is_occupied);
                    if h < occupied_below {
                        assert_eq!(call, Some(true), "τ {tau}: {h} above the top");
                        occupied += 1;
                    } else if h > free_above {
                        assert_eq!(call, Some(false), "τ {tau}: {h} above the top");
                        free += 1;
                    }
                }
            }
            assert!(free >= 12, "{free}");
            assert!(occupied >= 8 || tau > 0.5, "{occupied}");
        }
    }

    #[test]
    fn the_belief_knows_the_registered_truths_cells_and_is_reproducible() {
        let dir = tempfile::tempdir().unwrap();
        let experiment = along_z(dir.path(), 1.0, "threshold = 0.5, draws = 8");
        let seed = 2;
        let run = simulate(&experiment, seed, |_| {}).unwrap();
        let offset = experiment.map_offset(seed);
        let region = KeyBox::ALL;
        let belief = registration_belief(&experiment, &run.truth, seed, &offset, &region);
        let again = registration_belief(&experiment, &run.truth, seed, &offset, &region);
        assert_eq!(belief.leaves(), again.leaves());
        let other = registration_belief(&experiment, &run.truth, seed + 1, &offset, &region);
        assert_ne!(belief.leaves(), other.leaves(), "each seed draws its own");
        let truth = registered_truth(&experiment, &run.truth, 0.01, &offset, &region);
        let cells = |tree: &Octree| {
            let mut n = 0u64;
            tree.visit_leaves(|leaf| n += 1u64 << (3 * (DEPTH - leaf.depth) as u64));
            n
        };
        assert_eq!(cells(&belief), cells(&truth));
    }

    #[test]
    fn the_settings_are_checked() {
        let settings = |threshold, draws| BeliefSettings { threshold, draws };
        assert_eq!(settings(0.5, 32).checked().unwrap().votes_needed(), 17);
        assert_eq!(settings(0.475, 32).checked().unwrap().votes_needed(), 16);
        assert_eq!(settings(0.01, 1).checked().unwrap().votes_needed(), 1);
        for (threshold, draws) in [(0.0, 32), (1.0, 32), (f64::NAN, 32), (0.5, 0), (0.5, 5000)] {
            let e = settings(threshold, draws).checked().unwrap_err();
            assert!(e.starts_with("[registration_belief] "), "{e}");
        }
    }
}
