//! Simulating one viewpoint: ray casting from the true sensor pose, range
//! noise, jitter and dropout; what the modeller receives and what is kept
//! aside for scoring.

use super::scene::Scene;
use super::sensor::Scanner;
use super::streams::{Stream, Streams, BEAM_BLOCK};
use crate::geometry::{Isometry3, Point3, Vector3};
use crate::mapping::scan::{BeamStatus, Measurement};
use crate::uncertainty::RangeModel;
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;

/// What really happened to one beam (scoring only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamTruth {
    /// The true range to the first surface along the true beam; NaN when the
    /// beam reached nothing within the maximum range.
    pub range: f64,
    /// The true first surface point in the scene frame (NaN when none).
    pub point: Point3,
    /// The index of the object hit (`u32::MAX` when none).
    pub object: u32,
}

/// The truth behind a scan, kept aside for scoring only.
#[derive(Clone, Debug)]
pub struct ScanTruth {
    /// The true `scene_from_camera`.
    pub scene_from_camera: Isometry3,
    /// The frame's range scale `1 + s` ([`frame_scale`]): 1 without a
    /// scale error.
    pub range_scale: f64,
    /// One entry per beam.
    pub beams: Vec<BeamTruth>,
}

/// Rotates the unit vector `d` by the small angles `(a, b)` about two axes
/// perpendicular to it: `cos θ d + sin θ u`, `θ = |(a, b)|`.
#[inline]
fn jitter(d: &Vector3, a: f64, b: f64) -> Vector3 {
    let theta = (a * a + b * b).sqrt();
    if theta == 0.0 {
        return *d;
    }
    let helper = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = d.cross(&helper).normalize();
    let e2 = d.cross(&e1);
    let u = (e1 * a + e2 * b) / theta;
    d * theta.cos() + u * theta.sin()
}

/// Casts every beam of `scanner` from the true `scene_from_camera`, applying
/// the range model (the frame's scale error, [`frame_scale`], to every
/// range). Beams run in parallel in blocks of [`BEAM_BLOCK`], each
/// block with its own random stream, so the result does not depend on the
/// thread count. Every beam consumes four normals/uniforms whatever happens,
/// so changing one error level keeps the other draws (common random numbers).
pub fn cast_beams(
    scene: &Scene,
    scanner: &Scanner,
    range: &RangeModel,
    scene_from_camera: &Isometry3,
    streams: &Streams,
    viewpoint: u32,
) -> (Vec<Measurement>, Vec<BeamTruth>) {
    let n = scanner.directions().len();
    let mut measurements = vec![
        Measurement {
            status: BeamStatus::NoReturn,
            range: f64::NAN,
        };
        n
    ];
    let none = BeamTruth {
        range: f64::NAN,
        point: Point3::new(f64::NAN, f64::NAN, f64::NAN),
        object: u32::MAX,
    };
    let mut truth = vec![none; n];
    let origin = Point3::from(scene_from_camera.translation.vector);
    let rotation = scene_from_camera.rotation.to_rotation_matrix();
    let scale = frame_scale(range, streams, viewpoint);
    measurements
        .par_chunks_mut(BEAM_BLOCK)
        .zip(truth.par_chunks_mut(BEAM_BLOCK))
        .zip(scanner.directions().par_chunks(BEAM_BLOCK))
        .enumerate()
        .for_each(|(block, ((out, true_out), directions))| {
            let mut rng = streams.rng(Stream::Beams {
                viewpoint,
                block: block as u32,
            });
            for ((m, t), d) in out.iter_mut().zip(true_out.iter_mut()).zip(directions) {
                let a: f64 = rng.sample(StandardNormal);
                let b: f64 = rng.sample(StandardNormal);
                let u: f64 = rng.random();
                let noise: f64 = rng.sample(StandardNormal);
                let true_dir =
                    rotation * jitter(d, a * range.angular_sigma, b * range.angular_sigma);
                let Some((toi, object)) = scene.cast_ray(&origin, &true_dir, scanner.max_range)
                else {
                    continue;
                };
                *t = BeamTruth {
                    range: toi,
                    point: origin + true_dir * toi,
                    object: object as u32,
                };
                *m = if toi < scanner.min_range {
                    Measurement {
                        status: BeamStatus::TooClose,
                        range: f64::NAN,
                    }
                } else if u < range.dropout {
                    Measurement {
                        status: BeamStatus::Dropout,
                        range: f64::NAN,
                    }
                } else {
                    Measurement {
                        status: BeamStatus::Hit,
                        range: toi * scale + range.sigma(d, toi) * noise,
                    }
                };
            }
        });
    (measurements, truth)
}

/// The factor `1 + s`, `s ~ N(0, scale_sigma²)`, by which every range of
/// `viewpoint`'s frame is measured too long (docs/math.md §4.5): drawn from
/// the viewpoint's own stream, and exactly 1 without a scale error.
pub fn frame_scale(range: &RangeModel, streams: &Streams, viewpoint: u32) -> f64 {
    if range.scale_sigma == 0.0 {
        return 1.0;
    }
    let s: f64 = streams
        .rng(Stream::FrameScale(viewpoint))
        .sample(StandardNormal);
    1.0 + range.scale_sigma * s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::sensor::{ScannerSpec, SensorModel};
    use crate::uncertainty::RangeAxis;

    fn sphere_scene(dir: &std::path::Path) -> Scene {
        let path = dir.join("s.toml");
        std::fs::write(
            &path,
            "[workspace]\nmin = [-3, -3, -3]\nmax = [3, 3, 3]\n[[object]]\nshape = \"sphere\"\nradius = 0.5\nxyz = [0, 0, 2]\n",
        )
        .unwrap();
        Scene::load(&path).unwrap()
    }

    /// A square raster `fov_deg` across in steps of `step_deg`, 0.1–5 m.
    fn raster(fov_deg: f64, step_deg: f64) -> Scanner {
        ScannerSpec {
            model: SensorModel::Raster,
            horizontal_fov_deg: fov_deg,
            horizontal_step_deg: Some(step_deg),
            width: None,
            height: None,
            vertical_fov_deg: fov_deg,
            vertical_step_deg: None,
            min_range: 0.1,
            max_range: 5.0,
        }
        .build()
        .unwrap()
    }

    #[test]
    fn exact_sensor_measures_the_sphere() {
        let dir = tempfile::tempdir().unwrap();
        let scene = sphere_scene(dir.path());
        let scanner = raster(40.0, 1.0);
        let exact = RangeModel::NOISELESS;
        let (m, t) = cast_beams(
            &scene,
            &scanner,
            &exact,
            &Isometry3::identity(),
            &Streams::new(1),
            0,
        );
        let mut hits = 0;
        for ((m, t), d) in m.iter().zip(&t).zip(scanner.directions()) {
            // Analytic ray-sphere distance from the origin along d.
            // |t d − c|² = r² with c = (0, 0, 2): t² − 4 d_z t + 3.75 = 0.
            let b = -4.0 * d.z;
            let disc = b * b / 4.0 - (4.0 - 0.25);
            if disc < -1e-9 {
                assert_eq!(m.status, BeamStatus::NoReturn);
                assert!(t.range.is_nan());
            } else if disc > 1e-9 {
                hits += 1;
                let expected = -b / 2.0 - disc.sqrt();
                assert_eq!(m.status, BeamStatus::Hit);
                assert!((m.range - expected).abs() < 1e-12);
                assert!((t.point.coords - d * expected).norm() < 1e-12);
            }
        }
        assert!(hits > 100);
        // Beyond max range: no return, never a hit.
        let short = Scanner {
            max_range: 1.0,
            ..scanner.clone()
        };
        let (m, _) = cast_beams(
            &scene,
            &short,
            &exact,
            &Isometry3::identity(),
            &Streams::new(1),
            0,
        );
        assert!(m
            .iter()
            .all(|m| m.status == BeamStatus::NoReturn && m.range.is_nan()));
    }

    /// `z` has mean 0 and variance 1 within 5 standard errors (mean SE
    /// 1/√n, variance SE √(2/(n−1))).
    fn assert_standard_normal(z: &[f64]) {
        let n = z.len() as f64;
        let mean = z.iter().sum::<f64>() / n;
        let var = z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        assert!(mean.abs() < 5.0 / n.sqrt(), "mean {mean}");
        assert!(
            (var - 1.0).abs() < 5.0 * (2.0 / (n - 1.0)).sqrt(),
            "var {var}"
        );
    }

    #[test]
    fn range_noise_has_the_model_sigma() {
        let dir = tempfile::tempdir().unwrap();
        let scene = sphere_scene(dir.path());
        let scanner = raster(10.0, 0.05);
        let model = RangeModel {
            sigma0: 0.001,
            k: 0.002,
            k2: 0.004,
            angular_sigma: 0.0,
            dropout: 0.1,
            scale_sigma: 0.0,
            along: RangeAxis::Ray,
        };
        let (m, t) = cast_beams(
            &scene,
            &scanner,
            &model,
            &Isometry3::identity(),
            &Streams::new(5),
            0,
        );
        let z: Vec<f64> = m
            .iter()
            .zip(&t)
            .zip(scanner.directions())
            .filter(|((m, _), _)| m.status == BeamStatus::Hit)
            .map(|((m, t), d)| (m.range - t.range) / model.sigma(d, t.range))
            .collect();
        assert_standard_normal(&z);
        let n = z.len() as f64;
        let dropped = m.iter().filter(|m| m.status == BeamStatus::Dropout).count() as f64;
        let p = dropped / (dropped + n);
        assert!(
            (p - 0.1).abs() < 5.0 * (0.09 / (dropped + n)).sqrt(),
            "dropout {p}"
        );
    }

    /// A depth camera's error is its depth's: facing a wall square to its
    /// optical axis, every pixel's depth (the range times the cosine of its
    /// angle to the axis) has the σ the model gives that depth, in the
    /// image's corners as at its centre, where an error along the ray would
    /// give the corners' depths less (by that cosine).
    #[test]
    fn a_depth_cameras_error_is_the_same_on_every_pixel_of_a_wall() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("wall.toml");
        std::fs::write(
            &path,
            "[workspace]\nmin = [-3, -3, -1]\nmax = [3, 3, 3]\n[[object]]\nshape = \"box\"\n\
             size = [5, 5, 0.1]\nxyz = [0, 0, 1.55]\n",
        )
        .unwrap();
        let scene = Scene::load(&path).unwrap();
        let scanner = ScannerSpec {
            model: SensorModel::Pinhole,
            horizontal_fov_deg: 87.0,
            horizontal_step_deg: None,
            width: Some(212),
            height: Some(120),
            vertical_fov_deg: 0.0,
            vertical_step_deg: None,
            min_range: 0.1,
            max_range: 5.0,
        }
        .build()
        .unwrap();
        let model = RangeModel {
            sigma0: 0.0005,
            k2: 0.0036,
            along: RangeAxis::Depth,
            ..RangeModel::NOISELESS
        };
        // The wall's face is 1.5 m deep: σ(z) = 8.6 mm at every pixel.
        let depth_sigma = 0.0005 + 0.0036 * 1.5 * 1.5;
        let (m, t) = cast_beams(
            &scene,
            &scanner,
            &model,
            &Isometry3::identity(),
            &Streams::new(9),
            0,
        );
        // Standardised depth errors of the pixels within 20 deg of the
        // axis and of those beyond 40 deg (the corners, cos θ 0.67–0.77).
        let (mut centre, mut corners) = (Vec::new(), Vec::new());
        for ((m, t), d) in m.iter().zip(&t).zip(scanner.directions()) {
            assert_eq!(m.status, BeamStatus::Hit);
            assert!((t.range * d.z - 1.5).abs() < 1e-9);
            let z = (m.range - t.range) * d.z / depth_sigma;
            match d.z.acos().to_degrees() {
                a if a < 20.0 => centre.push(z),
                a if a > 40.0 => corners.push(z),
                _ => {}
            }
        }
        for (name, z) in [("centre", centre), ("corners", corners)] {
            let n = z.len() as f64;
            assert!(n > 1000.0, "{name}: {n} pixels");
            let var = z.iter().map(|v| v * v).sum::<f64>() / n;
            // 5 standard errors of a variance, √(2/n).
            assert!(
                (var - 1.0).abs() < 5.0 * (2.0 / n).sqrt(),
                "{name}: depth variance {var} of the model's over {n} pixels"
            );
        }
    }

    /// Every range of a frame is `1 + s` times the true one, one `s` per
    /// viewpoint: over 400 viewpoints `s / s_σ` has mean 0 and variance 1
    /// (within 5 standard errors), the same seed draws the same `s`, and
    /// a profile without a scale error measures exactly as before.
    #[test]
    fn a_frames_ranges_share_one_scale_error() {
        let dir = tempfile::tempdir().unwrap();
        let scene = sphere_scene(dir.path());
        let scanner = raster(20.0, 2.0);
        let model = RangeModel {
            scale_sigma: 0.02,
            ..RangeModel::NOISELESS
        };
        let streams = Streams::new(3);
        let mut scales = Vec::new();
        for viewpoint in 0..400 {
            let (m, t) = cast_beams(
                &scene,
                &scanner,
                &model,
                &Isometry3::identity(),
                &streams,
                viewpoint,
            );
            let ratios: Vec<f64> = m
                .iter()
                .zip(&t)
                .filter(|(m, _)| m.status == BeamStatus::Hit)
                .map(|(m, t)| m.range / t.range)
                .collect();
            assert!(ratios.len() > 50, "{} hits", ratios.len());
            let scale = frame_scale(&model, &streams, viewpoint);
            for ratio in ratios {
                assert!(
                    (ratio - scale).abs() < 1e-12,
                    "{ratio} in a frame of {scale}"
                );
            }
            scales.push((scale - 1.0) / model.scale_sigma);
        }
        assert_standard_normal(&scales);
        assert_eq!(
            frame_scale(&model, &Streams::new(3), 7),
            frame_scale(&model, &streams, 7)
        );
        assert_eq!(frame_scale(&RangeModel::NOISELESS, &streams, 7), 1.0);
    }

    #[test]
    fn jitter_is_a_rotation_with_the_right_spread() {
        let d = Vector3::new(0.3, -0.2, 0.9).normalize();
        let j = jitter(&d, 0.01, -0.02);
        assert!((j.norm() - 1.0).abs() < 1e-15);
        assert!((d.dot(&j).acos() - (0.01f64.powi(2) + 0.02f64.powi(2)).sqrt()).abs() < 1e-12);
    }
}
