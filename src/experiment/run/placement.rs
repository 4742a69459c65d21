//! Where a scene stands against recorded scans (`sigmap score --scene`):
//! how many of the scans' returns the placed scene meets at their range,
//! and the rigid move that would bring it onto them.

use super::scoring::recorded_rays;
use crate::geometry::{Isometry3, Matrix6, Point3, Vector3, Vector6};
use crate::mapping::scan_graph::ScanNode;
use crate::sim::scene::Scene;

/// How well the recorded returns sit on the scene's surfaces where
/// `map_from_scene` puts the scene: a check of `--scene-pose` (and of the
/// scene's units and frame) that needs no map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceAgreement {
    /// Returns looked at: every hit, or an even sample of [`AGREEMENT_SAMPLE`].
    pub sampled: usize,
    /// Of those, the ones whose ray, cast on the scene, first meets a
    /// surface within `tolerance` of the recorded range.
    pub near: usize,
    /// The distance (m).
    pub tolerance: f64,
}

impl SurfaceAgreement {
    /// The share of the sampled returns near a surface (1 when none was
    /// sampled: nothing disagrees).
    pub fn share(&self) -> f64 {
        if self.sampled == 0 {
            1.0
        } else {
            self.near as f64 / self.sampled as f64
        }
    }
}

/// The most returns a [`Placement`] looks at.
pub const AGREEMENT_SAMPLE: usize = 20_000;

/// Below this share of returns near the scene's surfaces, `sigmap score
/// --scene` warns that the scene may be misplaced: a registered scan of a
/// modelled workcell puts nearly all its returns on the model.
pub const AGREEMENT_WARNING: f64 = 0.8;

/// The recorded returns (points within `max_range`, as [`recorded_rays`]
/// counts hits) a scene's placement is checked against: at most
/// [`AGREEMENT_SAMPLE`] of them, taken at an even stride in file order (the
/// same on every run), and how near its range a return's ray must meet the
/// scene to agree with it.
pub struct Placement<'a> {
    scene: &'a Scene,
    returns: Vec<Return>,
    tolerance: f64,
}

impl<'a> Placement<'a> {
    /// The returns of `nodes` against `scene`, agreeing within `tolerance`.
    pub fn new(
        scene: &'a Scene,
        nodes: &[ScanNode],
        max_range: Option<f64>,
        tolerance: f64,
    ) -> Self {
        Self {
            scene,
            returns: sampled_returns(nodes, max_range),
            tolerance,
        }
    }

    /// [`SurfaceAgreement`] with the scene placed by `map_from_scene`: a
    /// return agrees when its ray, cast from its scan's origin on the
    /// scene, first meets a surface within the tolerance of its recorded
    /// range (not before, as through a misplaced solid, nor never).
    pub fn agreement(&self, map_from_scene: &Isometry3) -> SurfaceAgreement {
        let scene_from_map = map_from_scene.inverse();
        let tolerance = self.tolerance;
        let near = self
            .returns
            .iter()
            .filter(|ray| {
                first_surface(self.scene, &scene_from_map, ray, tolerance)
                    .is_some_and(|miss| miss.abs() <= tolerance)
            })
            .count();
        SurfaceAgreement {
            sampled: self.returns.len(),
            near,
            tolerance,
        }
    }
}

/// A recorded return as a ray: origin, unit direction and range, map frame.
struct Return {
    origin: Point3,
    direction: Vector3,
    range: f64,
}

/// At most [`AGREEMENT_SAMPLE`] of the recorded returns (points within
/// `max_range`), at an even stride in file order.
fn sampled_returns(nodes: &[ScanNode], max_range: Option<f64>) -> Vec<Return> {
    let hits = || recorded_rays(nodes, max_range).filter(|ray| ray.hit);
    let stride = hits().count().div_ceil(AGREEMENT_SAMPLE).max(1);
    hits()
        .step_by(stride)
        .filter_map(|ray| {
            let range = (ray.end - ray.origin).norm();
            (range > 0.0).then(|| Return {
                origin: ray.origin,
                direction: (ray.end - ray.origin) / range,
                range,
            })
        })
        .collect()
}

/// Where `ray`, cast on the scene placed by `scene_from_map`, first meets a
/// surface, less the recorded range; `None` when it meets none before
/// `slack` past its range.
fn first_surface(
    scene: &Scene,
    scene_from_map: &Isometry3,
    ray: &Return,
    slack: f64,
) -> Option<f64> {
    let origin = scene_from_map * ray.origin;
    let direction = scene_from_map * ray.direction;
    scene
        .cast_ray(&origin, &direction, ray.range + slack)
        .map(|(first, _)| first - ray.range)
}

/// The rigid move (map frame) that best brings the scene onto the recorded
/// returns, where the returns fix it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refinement {
    /// The move: the scene fits best placed by `correction * map_from_scene`.
    /// It is the identity along the degrees of freedom the returns leave free.
    pub correction: Isometry3,
    /// How far the move takes the sampled returns' centroid (m).
    pub centroid_shift: Vector3,
    /// The farthest the move takes any sampled return's end point (m).
    pub largest_move: f64,
    /// How many of the six degrees of freedom (three translations, three
    /// turns about the returns' centroid) the returns fix.
    pub fixed: usize,
    /// How free each degree of freedom is, in the order x, y, z and the
    /// turns about x, y, z through the centroid (map axes): the squared
    /// length of its unit move projected on the moves the returns leave
    /// free (1: wholly free, 0: fixed; they add up to `6 − fixed`).
    pub freedom: [f64; 6],
    /// The agreement with the scene moved.
    pub agreement: SurfaceAgreement,
}

/// Gauss–Newton steps at most.
const REFINE_STEPS: usize = 12;

/// How far (in tolerances) a return's first surface may lie from its range
/// and still pull the scene: farther ones are other objects.
const REFINE_REACH: f64 = 8.0;

/// The moves a refinement is made of, in metres: a translation, and a turn
/// about `pivot` measured by how far it takes a point `lever` from its axis
/// (so that a turn and a translation of equal size move the returns alike,
/// and one threshold judges which the returns fix).
struct Moves {
    pivot: Vector3,
    lever: f64,
}

impl Moves {
    /// The move of parameters `p`: translation `p[0..3]`, turn `p[3..6] /
    /// lever` (axis-angle) about the pivot.
    fn of(&self, p: &Vector6) -> Isometry3 {
        let turn =
            nalgebra::UnitQuaternion::from_scaled_axis(Vector3::new(p[3], p[4], p[5]) / self.lever);
        let to_pivot = nalgebra::Translation3::from(self.pivot + Vector3::new(p[0], p[1], p[2]));
        let from_pivot = nalgebra::Translation3::from(-self.pivot);
        to_pivot * turn * from_pivot
    }
}

impl Placement<'_> {
    /// The rigid move of the scene (map frame) that brings the recorded
    /// returns' rays onto it: least squares on each ray's first surface less
    /// its range, over the returns within [`REFINE_REACH`] tolerances, in the
    /// three translations and the three turns about the returns' centroid;
    /// derivatives by moving the scene a tenth of a tolerance along each (a
    /// turn by the angle that moves a point at the returns' RMS distance
    /// from the centroid that far). A degree of freedom the returns do not
    /// fix (a single plane leaves three) is left unmoved. `None` when no
    /// return lies near enough to the scene to pull it.
    pub fn refine(&self, map_from_scene: &Isometry3) -> Option<Refinement> {
        let (scene, tolerance) = (self.scene, self.tolerance);
        let ends: Vec<Point3> = self
            .returns
            .iter()
            .map(|ray| ray.origin + ray.direction * ray.range)
            .collect();
        if ends.is_empty() {
            return None;
        }
        let count = ends.len() as f64;
        let pivot = ends.iter().map(|p| p.coords).sum::<Vector3>() / count;
        let spread = (ends
            .iter()
            .map(|p| (p.coords - pivot).norm_squared())
            .sum::<f64>()
            / count)
            .sqrt();
        let moves = Moves {
            pivot,
            lever: spread.max(tolerance),
        };
        let reach = REFINE_REACH * tolerance;
        let step = 0.1 * tolerance;
        let mut correction = Isometry3::identity();
        let (mut fixed, mut freedom) = (0, [0.0; 6]);
        for _ in 0..REFINE_STEPS {
            // The scene where it stands now, and moved a step along each
            // degree of freedom: cast from these frames.
            let placed = |m: &Isometry3| (m * map_from_scene).inverse();
            let here = placed(&correction);
            let stepped: [Isometry3; 6] =
                std::array::from_fn(|k| placed(&(moves.of(&Vector6::ith(k, step)) * correction)));
            let (mut normal, mut gradient, mut used) = (Matrix6::zeros(), Vector6::zeros(), 0);
            for ray in &self.returns {
                let Some(miss) =
                    first_surface(scene, &here, ray, reach + step).filter(|m| m.abs() <= reach)
                else {
                    continue;
                };
                let mut slope = Vector6::zeros();
                let moved = stepped.iter().enumerate().all(|(k, frame)| {
                    let along = first_surface(scene, frame, ray, reach + step);
                    along.map(|m| slope[k] = (m - miss) / step).is_some()
                });
                // A ray that slides off an edge when moved says nothing here.
                if !moved || slope.norm() > 10.0 {
                    continue;
                }
                normal += slope * slope.transpose();
                gradient += slope * miss;
                used += 1;
            }
            if used < 6 {
                return None;
            }
            let eigen = nalgebra::SymmetricEigen::new(normal);
            let largest = eigen.eigenvalues.max();
            let mut delta = Vector6::zeros();
            (fixed, freedom) = (0, [0.0; 6]);
            for k in 0..6 {
                let v = eigen.eigenvectors.column(k).into_owned();
                // A direction a thousandth as constrained as the best is free.
                if eigen.eigenvalues[k] > 1e-3 * largest {
                    delta -= v * (v.dot(&gradient) / eigen.eigenvalues[k]);
                    fixed += 1;
                } else {
                    for (share, c) in freedom.iter_mut().zip(v.iter()) {
                        *share += c * c;
                    }
                }
            }
            correction = moves.of(&delta) * correction;
            if delta.norm() < 1e-3 * tolerance {
                break;
            }
        }
        let largest_move = ends
            .iter()
            .map(|p| (correction * p - p).norm())
            .fold(0.0, f64::max);
        Some(Refinement {
            correction,
            centroid_shift: correction * Point3::from(pivot) - Point3::from(pivot),
            largest_move,
            fixed,
            freedom,
            agreement: self.agreement(&(correction * map_from_scene)),
        })
    }
}

#[cfg(test)]
mod tests;
