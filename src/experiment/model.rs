//! Building a map from a simulated run with one modelling method: what the
//! modeller can do with the scans alone (the truth never enters here).

use super::{Experiment, SimulatedRun};
use crate::geometry::{Point3, Vector3};
use crate::mapping::chord::CellModel;
use crate::mapping::merge::{merge, MergeOptions};
use crate::mapping::ray_update::RayUpdater;
use crate::mapping::spherical::BeamEnd;
use crate::mapping::viewpoint::{local_grid, Raster};
use crate::mapping::Octree;
use crate::sim::scan::{BeamStatus, Scan};
use crate::uncertainty::{
    BlindPropagator, JacobianPropagator, Propagator, SigmaSet, UncertainChain, UncertainPoint,
    UnscentedPropagator,
};
use rayon::prelude::*;
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
    /// OctoMap's ray update (hit/miss log-odds), the baseline most users run.
    RayUpdate,
}

impl Method {
    /// Every method.
    pub const ALL: [Method; 4] = [
        Method::Blind,
        Method::Jacobian,
        Method::Unscented,
        Method::RayUpdate,
    ];

    /// Its name in files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Blind => "blind",
            Method::Jacobian => "jacobian",
            Method::Unscented => "unscented",
            Method::RayUpdate => "ray_update",
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
                format!("unknown method '{s}' (use blind, jacobian, unscented or ray_update)")
            })
    }
}

/// The propagator of an OPDF method for one viewpoint's chain; `None` for
/// the ray update, which propagates nothing.
pub fn propagator(method: Method, chain: &UncertainChain) -> Option<Box<dyn Propagator>> {
    match method {
        Method::Blind => Some(Box::new(BlindPropagator::new(chain))),
        Method::Jacobian => Some(Box::new(JacobianPropagator::new(chain))),
        Method::Unscented => Some(Box::new(UnscentedPropagator::new(chain, SigmaSet::Paper))),
        Method::RayUpdate => None,
    }
}

/// The chain of a scan as the modeller believes it.
pub fn scan_chain(scan: &Scan) -> UncertainChain {
    UncertainChain::paper(
        scan.chain.world_from_scene,
        scan.chain.world_from_robot,
        scan.chain.robot_from_camera,
    )
}

/// The propagated beam ends of one scan (hits with covariances, no-return
/// beams as directions; too-close and dropped beams carry nothing), and the
/// propagated origin.
pub fn beam_ends(
    experiment: &Experiment,
    scan: &Scan,
    propagator: &dyn Propagator,
) -> Vec<BeamEnd> {
    let rotation = scan
        .chain
        .scene_from_camera()
        .rotation
        .to_rotation_matrix()
        .into_inner();
    let range = &experiment.profile.range;
    scan.measurements
        .par_iter()
        .zip(experiment.scanner.directions.par_iter())
        .filter_map(|(m, d)| match m.status {
            BeamStatus::Hit => {
                let g = propagator.propagate(&UncertainPoint {
                    mean: d * m.range,
                    covariance: range.point_covariance(d, m.range),
                });
                Some(BeamEnd::Hit {
                    point: g.mean,
                    covariance: g.covariance,
                })
            }
            BeamStatus::NoReturn => Some(BeamEnd::Miss {
                direction: rotation * d,
            }),
            BeamStatus::TooClose | BeamStatus::Dropout => None,
        })
        .collect()
}

/// For each hit of a scan: the error `truth − propagated mean` and the
/// propagated covariance, for consistency checks against the simulator.
pub fn beam_ends_with_truth(
    experiment: &Experiment,
    scan: &Scan,
    propagator: &dyn Propagator,
) -> Vec<(Vector3, crate::geometry::Matrix3)> {
    let range = &experiment.profile.range;
    scan.measurements
        .iter()
        .zip(&experiment.scanner.directions)
        .zip(&scan.truth.beams)
        .filter(|((m, _), _)| m.status == BeamStatus::Hit)
        .map(|((m, d), t)| {
            let g = propagator.propagate(&UncertainPoint {
                mean: d * m.range,
                covariance: range.point_covariance(d, m.range),
            });
            (t.point.coords - g.mean, g.covariance)
        })
        .collect()
}

/// Builds the map of a run at `resolution` with `method`, in the map frame
/// `map = scene + offset` (zero: the scene frame; see `Experiment::map_offset`).
pub fn build_map(
    experiment: &Experiment,
    run: &SimulatedRun,
    method: Method,
    resolution: f64,
    offset: &Vector3,
) -> Octree {
    let mut tree = Octree::new(resolution);
    let raster = Raster {
        horizontal: &experiment.scanner.horizontal_angles,
        vertical: &experiment.scanner.vertical_angles,
    };
    let max_range = experiment.scanner.max_range;
    let options = MergeOptions {
        model: CellModel::with_risk(experiment.risk),
        ..MergeOptions::default()
    };
    let mut updater = RayUpdater::default();
    for scan in &run.scans {
        let chain = scan_chain(scan);
        let Some(propagator) = propagator(method, &chain) else {
            let (mut origin, mut hits, misses) = ray_inputs(experiment, scan);
            origin += offset;
            hits.iter_mut().for_each(|h| *h += offset);
            updater.insert_scan(&mut tree, &origin, &hits, &misses, max_range);
            continue;
        };
        let origin = propagator.origin();
        let mut beams = beam_ends(experiment, scan, propagator.as_ref());
        for beam in &mut beams {
            if let BeamEnd::Hit { point, .. } = beam {
                *point += offset;
            }
        }
        let rotation = chain.nominal().rotation.to_rotation_matrix().into_inner();
        let grid = local_grid(
            &(origin.mean + offset),
            &origin.covariance,
            &rotation,
            raster,
            &beams,
            max_range,
        );
        merge(&mut tree, &grid, &options);
    }
    tree.shrink_to_fit();
    tree
}

/// The nominal origin, measured end points and no-return directions of a
/// scan, in the scene frame (what OctoMap's `insertPointCloud` is given).
pub fn ray_inputs(experiment: &Experiment, scan: &Scan) -> (Point3, Vec<Point3>, Vec<Vector3>) {
    let pose = scan.chain.scene_from_camera();
    let origin = Point3::from(pose.translation.vector);
    let mut hits = Vec::with_capacity(scan.measurements.len());
    let mut misses = Vec::new();
    for (m, d) in scan.measurements.iter().zip(&experiment.scanner.directions) {
        match m.status {
            BeamStatus::Hit => hits.push(pose * Point3::from(d * m.range)),
            BeamStatus::NoReturn => misses.push(pose.rotation * d),
            _ => {}
        }
    }
    (origin, hits, misses)
}
