//! Where a scene stands against recorded scans (`sigmap score --scene`):
//! how many of the scans' returns the placed scene meets at their range,
//! and the translation that would bring it onto them.

use super::scoring::recorded_rays;
use crate::geometry::{Isometry3, Matrix3, Point3, Vector3};
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
                first_surface(
                    self.scene,
                    &scene_from_map,
                    ray,
                    Vector3::zeros(),
                    tolerance,
                )
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

/// Where `ray`, cast on the scene moved by `shift` (map frame), first meets
/// a surface, less the recorded range; `None` when it meets none before
/// `slack` past its range. Moving the scene by `shift` is casting from
/// the origin moved by `−shift`.
fn first_surface(
    scene: &Scene,
    scene_from_map: &Isometry3,
    ray: &Return,
    shift: Vector3,
    slack: f64,
) -> Option<f64> {
    let origin = scene_from_map * (ray.origin - shift);
    let direction = scene_from_map * ray.direction;
    scene
        .cast_ray(&origin, &direction, ray.range + slack)
        .map(|(first, _)| first - ray.range)
}

/// The translation (map frame) that best moves the scene onto the recorded
/// returns, where the returns fix it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refinement {
    /// The scene's move (m), zero along the axes the returns leave free.
    pub shift: Vector3,
    /// How many of the three directions the returns fix.
    pub fixed: usize,
    /// The agreement with the scene moved.
    pub agreement: SurfaceAgreement,
}

/// Gauss–Newton steps at most.
const REFINE_STEPS: usize = 8;

/// How far (in tolerances) a return's first surface may lie from its range
/// and still pull the scene: farther ones are other objects.
const REFINE_REACH: f64 = 8.0;

impl Placement<'_> {
    /// The scene's translation that brings the recorded returns' rays onto it
    /// (least squares on each ray's first surface less its range, over the
    /// returns within [`REFINE_REACH`] tolerances; derivatives by moving the
    /// scene a tenth of a tolerance along each axis). A direction the returns
    /// do not fix (a single plane leaves two) is left unmoved. `None` when no
    /// return lies near enough to the scene to pull it.
    pub fn refine(&self, map_from_scene: &Isometry3) -> Option<Refinement> {
        let (scene, tolerance) = (self.scene, self.tolerance);
        let scene_from_map = map_from_scene.inverse();
        let reach = REFINE_REACH * tolerance;
        let step = 0.1 * tolerance;
        let mut shift = Vector3::zeros();
        let mut fixed = 0;
        for _ in 0..REFINE_STEPS {
            let (mut normal, mut gradient, mut used) = (Matrix3::zeros(), Vector3::zeros(), 0);
            for ray in &self.returns {
                let at = |s: Vector3| first_surface(scene, &scene_from_map, ray, s, reach + step);
                let Some(miss) = at(shift).filter(|m| m.abs() <= reach) else {
                    continue;
                };
                let mut slope = Vector3::zeros();
                let moved = (0..3).all(|axis| {
                    let along = at(shift + Vector3::ith(axis, step));
                    along.map(|m| slope[axis] = (m - miss) / step).is_some()
                });
                // A ray that slides off an edge when moved says nothing here.
                if !moved || slope.norm() > 10.0 {
                    continue;
                }
                normal += slope * slope.transpose();
                gradient += slope * miss;
                used += 1;
            }
            if used < 3 {
                return None;
            }
            let (values, vectors) = crate::geometry::symmetric_eigen(&normal);
            let largest = values.max();
            let mut delta = Vector3::zeros();
            fixed = 0;
            for k in 0..3 {
                // A direction a thousandth as constrained as the best is free.
                if values[k] > 1e-3 * largest {
                    let v = vectors.column(k).into_owned();
                    delta -= v * (v.dot(&gradient) / values[k]);
                    fixed += 1;
                }
            }
            shift += delta;
            if delta.norm() < 1e-3 * tolerance {
                break;
            }
        }
        let moved = nalgebra::Translation3::from(shift) * map_from_scene;
        Some(Refinement {
            shift,
            fixed,
            agreement: self.agreement(&moved),
        })
    }
}

#[cfg(test)]
mod tests;
