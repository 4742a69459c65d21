use super::*;
use crate::geometry::Matrix3;
use crate::mapping::settings::SampleGate;
use crate::mapping::spherical::{Axis, BeamEnd, GridBuffers, GridLayout};
use crate::uncertainty::RangeModel;

/// Bin width (rad) of the test grids.
const STEP: f64 = 0.01;

fn axis(count: usize) -> Axis {
    Axis {
        start: -(count as f64) * STEP / 2.0,
        step: STEP,
        count,
    }
}

/// One beam per bin, along the bin's centre direction, ending at
/// `range(direction)` with isotropic noise σ (so σ along the beam).
fn grid_of(na: usize, ne: usize, sigma: f64, range: impl Fn(&Vector3) -> f64) -> LocalGrid {
    let (azimuth, elevation) = (axis(na), axis(ne));
    let mut ends = Vec::new();
    for a in 0..na {
        for e in 0..ne {
            let (az, el) = (azimuth.centre(a), elevation.centre(e));
            let d = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            ends.push(BeamEnd::Hit {
                point: d * range(&d),
                covariance: Matrix3::identity() * sigma * sigma,
            });
        }
    }
    let layout = GridLayout {
        origin: Vector3::zeros(),
        scene_from_grid: Matrix3::identity(),
        azimuth,
        elevation,
        max_range: 2.0,
    };
    let ends = (ends.len(), |i: usize| Some(ends[i]));
    LocalGrid::from_ends_in(
        GridBuffers::default(),
        layout,
        None,
        ends,
        &(Matrix3::identity() * 1e-6),
    )
}

/// The slanted plane `n · p = 0.5` the sensor faces.
fn plane_normal() -> Vector3 {
    Vector3::new(1.0, 0.3, -0.2).normalize()
}

#[test]
fn every_block_of_a_plane_is_sampled_once_on_the_plane() {
    let (na, ne) = (12, 9);
    let n = plane_normal();
    let mut grid = grid_of(na, ne, 0.001, |d| 0.5 / n.dot(d));
    grid.add_surface_samples(
        &SampleGate::default(),
        (&RangeModel::NOISELESS, &Matrix3::identity()),
    );
    let (samples, inverse) = grid.samples();
    // Every block is sampled and every lattice point of the blocks taken
    // once: the whole lattice of STEPS per spacing but the beams' own.
    let lattice = ((na - 1) * STEPS + 1) * ((ne - 1) * STEPS + 1);
    assert_eq!(samples.len(), lattice - na * ne);
    assert_eq!(inverse.len(), samples.len());
    let mut worst = 0.0f64;
    for (s, inv) in samples.iter().zip(inverse) {
        let point = s.direction * s.range;
        // Bilinear in angle: off the plane by second-order terms only.
        worst = worst.max((n.dot(&point) - 0.5).abs());
        assert!((s.sigma - 0.001).abs() < 1e-12 && s.sigma_origin >= 0.0);
        assert_eq!(*inv, s.direction.map(|c| 1.0 / c));
    }
    // Second order in the spacing Δ: within r Δ² (measured 1.3e-5 m).
    assert!(worst < 0.5 * STEP * STEP, "{worst:e}");
    // Unique directions: no point taken twice.
    let mut keys: Vec<_> = samples
        .iter()
        .map(|s| (s.direction * 1e9).map(|c| c.round() as i64))
        .map(|v| (v.x, v.y, v.z))
        .collect();
    keys.sort_unstable();
    keys.dedup();
    assert_eq!(keys.len(), samples.len());
}

#[test]
fn no_sample_bridges_a_step_between_two_surfaces() {
    // A wall at 0.5 m on one side, 0.6 m on the other: blocks across the
    // step fail the windows' test, so no sample lies between the two.
    let sigma = 0.001;
    let mut grid = grid_of(16, 9, sigma, |d| if d.y < 0.0 { 0.5 } else { 0.6 } / d.x);
    grid.add_surface_samples(
        &SampleGate::default(),
        (&RangeModel::NOISELESS, &Matrix3::identity()),
    );
    let (samples, _) = grid.samples();
    let depth = |s: &Beam| s.direction.x * s.range;
    assert!(samples.iter().any(|s| (depth(s) - 0.5).abs() < 1e-4));
    assert!(samples.iter().any(|s| (depth(s) - 0.6).abs() < 1e-4));
    let bridging = samples
        .iter()
        .filter(|s| depth(s) > 0.5 + 10.0 * sigma && depth(s) < 0.6 - 10.0 * sigma)
        .count();
    assert_eq!(bridging, 0);
}

#[test]
fn samples_widen_the_bins_band_summaries() {
    // The merge skips cells by the bins' summaries: each sample's band must
    // lie inside its bin's [near, far].
    let n = plane_normal();
    let mut grid = grid_of(10, 8, 0.004, |d| 0.5 / n.dot(d));
    grid.add_surface_samples(
        &SampleGate::default(),
        (&RangeModel::NOISELESS, &Matrix3::identity()),
    );
    let (samples, _) = grid.samples();
    assert!(!samples.is_empty());
    for s in samples {
        let (a, e) = grid.bin_of(&s.direction).expect("inside the grid");
        let bin = grid.bin_summary(a, e);
        assert!(bin.near <= s.band_start(grid.max_range));
        assert!(bin.far >= s.reach(grid.max_range));
        let top = grid.query((0, grid.azimuth.count - 1), (0, grid.elevation.count - 1));
        assert!(top.near <= bin.near && top.far >= bin.far);
    }
}
