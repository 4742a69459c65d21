//! The modelling methods and what each propagates: the method table every
//! map builder and every sweep draws from, the propagator of each OPDF
//! method, and the chain split of the `correlated` method (docs/math.md §6.6).

use super::scan::Scan;
use crate::geometry::Matrix6;
use crate::uncertainty::{
    BlindPropagator, JacobianPropagator, Propagator, SigmaSet, UncertainChain, UnscentedPropagator,
};
use std::fmt;
use std::str::FromStr;

/// How a map is built.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Method {
    /// OPDF merge, range covariance only (chain exact).
    Blind,
    /// OPDF merge, covariances by first-order propagation.
    Jacobian,
    /// OPDF merge, covariances by the unscented transform.
    Unscented,
    /// The unscented OPDF merge with the viewpoints fused on their own
    /// (arm) error only, and the shared errors (T_sw, T_cr, one draw per run)
    /// accounted once on the fused map (docs/math.md §6.6).
    Correlated,
    /// OctoMap's ray update (hit/miss log-odds), the baseline most users run.
    RayUpdate,
    /// OctoMap's ray update with its discretized insertion
    /// (`insertPointCloud(..., discretize = true)`): one ray per scan to the
    /// centre of each cell a beam ended in ([`DiscreteScan`]).
    ///
    /// [`DiscreteScan`]: super::ray_update::DiscreteScan
    RayUpdateDiscrete,
    /// Not a mapper: the true occupancy as the run's drawn scene registration
    /// (T_sw) places it, what a perfect sensor on a perfect arm would map.
    /// A scoring reference for `sigmap run` (`runner::registered_truth`): the
    /// ceiling for any map that cannot see the registration error.
    RegisteredTruth,
    /// Not a mapper: the true occupancy as the run's scans together place
    /// it, moved by the registration's error and by the viewpoints' mean
    /// displacement, which no map built from the scans alone can undo
    /// (`experiment::run::consensus_truth`, docs/math.md §7.5). A scoring reference
    /// for `sigmap run`.
    ConsensusTruth,
    /// Not a mapper: the registered truth blurred over draws of the
    /// registration's told covariance, called occupied where more than a
    /// threshold of the draws put a solid (`[registration_belief]`,
    /// `experiment::run::registration_belief`, docs/math.md §7.5): what a
    /// map that knows the registration's covariance and nothing else wrong
    /// would believe. A scoring reference for `sigmap run`.
    RegistrationBelief,
}

impl Method {
    /// Every method.
    pub const ALL: [Method; 9] = [
        Method::Blind,
        Method::Jacobian,
        Method::Unscented,
        Method::Correlated,
        Method::RayUpdate,
        Method::RayUpdateDiscrete,
        Method::RegisteredTruth,
        Method::ConsensusTruth,
        Method::RegistrationBelief,
    ];

    /// Whether it builds local grids from propagated beams (the OPDF
    /// methods), not rays or the truth.
    pub fn builds_grids(self) -> bool {
        !(self.casts_rays() || self.is_truth())
    }

    /// Whether it is a scoring reference made from a simulated run's truth
    /// (`registered_truth`, `consensus_truth`, `registration_belief`), not a
    /// map built from scans.
    pub fn is_truth(self) -> bool {
        matches!(
            self,
            Method::RegisteredTruth | Method::ConsensusTruth | Method::RegistrationBelief
        )
    }

    /// Whether it is OctoMap's ray update (either insertion).
    pub fn casts_rays(self) -> bool {
        matches!(self, Method::RayUpdate | Method::RayUpdateDiscrete)
    }

    /// Its name in files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Blind => "blind",
            Method::Jacobian => "jacobian",
            Method::Unscented => "unscented",
            Method::Correlated => "correlated",
            Method::RayUpdate => "ray_update",
            Method::RayUpdateDiscrete => "ray_update_discrete",
            Method::RegisteredTruth => "registered_truth",
            Method::ConsensusTruth => "consensus_truth",
            Method::RegistrationBelief => "registration_belief",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Method::ALL.iter().map(|m| m.as_str()).collect();
                let (last, rest) = names.split_last().expect("methods");
                format!("unknown method '{s}' (use {} or {last})", rest.join(", "))
            })
    }
}

/// Why scans cannot give `method`, a scoring reference ([`Method::is_truth`]).
pub fn truth_from_scans(method: Method) -> String {
    format!(
        "{method} is a scoring reference built from a simulated run's truth, not from scans: \
         give an experiment (`sigmap map EXPERIMENT --method {method}`, or list it in the \
         experiment's `methods` for `sigmap run`)"
    )
}

/// The propagator of an OPDF method for one viewpoint's chain: the
/// per-point marginal (for `correlated`, the full covariance, as its
/// consistency is checked), sigma-point methods with `sigma_set`; `None` for
/// the ray update, which propagates nothing.
pub fn propagator(
    method: Method,
    chain: &UncertainChain,
    sigma_set: SigmaSet,
) -> Option<Box<dyn Propagator>> {
    match method {
        Method::Blind => Some(Box::new(BlindPropagator::new(chain))),
        Method::Jacobian => Some(Box::new(JacobianPropagator::new(chain))),
        Method::Unscented | Method::Correlated => {
            Some(Box::new(UnscentedPropagator::new(chain, sigma_set)))
        }
        Method::RayUpdate
        | Method::RayUpdateDiscrete
        | Method::RegisteredTruth
        | Method::ConsensusTruth
        | Method::RegistrationBelief => None,
    }
}

/// The links drawn once per run (scene registration, hand-eye): shared by
/// every viewpoint of a run (docs/math.md §6.6).
const SHARED_LINKS: [&str; 2] = ["world_from_scene", "robot_from_camera"];

/// `chain` with only the shared links uncertain (`shared`) or only the
/// others (`!shared`).
pub fn split_chain(chain: &UncertainChain, shared: bool) -> UncertainChain {
    let mut out = chain.clone();
    for link in &mut out.links {
        if SHARED_LINKS.contains(&link.name.as_str()) != shared {
            link.pose.covariance = Matrix6::zeros();
        }
    }
    out
}

/// The chain of a scan as the modeller believes it.
pub fn scan_chain(scan: &Scan) -> UncertainChain {
    UncertainChain::paper(
        scan.chain.world_from_scene,
        scan.chain.world_from_robot,
        scan.chain.robot_from_camera,
    )
}
