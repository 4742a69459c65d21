//! What a scan measured, as each method draws it: the measured range of
//! every beam (raw, or pooled on the surfaces the beams share, docs/math.md
//! §5.5), the point a map draws from it, the point the NEES checks, and the
//! rays OctoMap's update inserts.

use super::pooling::{pool_ranges, Pooled, PooledRange, Pooling};
use super::scan::{BeamLayout, BeamStatus, GridMember, MapperView, Measurement, Scan};
use crate::geometry::{Point3, Vector3};
use crate::uncertainty::{RangeModel, UncertainPoint};

/// A beam's measured range if it hit.
#[inline]
fn hit_range(m: &Measurement) -> Option<f64> {
    (m.status == BeamStatus::Hit).then_some(m.range)
}

/// What a scan measured along each beam (`None`: no hit) as the
/// uncertainty-aware methods draw it: the raw range with the range model's
/// σ, or with `beam_pooling` the range pooled on its grid's local plane or
/// face (docs/math.md §5.5). The same for every such method: compute it once
/// per scan. [`surface_point`] is what a map draws from it, [`hit_point`]
/// what the NEES checks. Fails when pooling needs a regular raster and two
/// beams share a grid bin.
pub fn measured_ranges(
    view: &MapperView,
    layout: &BeamLayout,
    scan: &Scan,
) -> Result<Vec<Pooled>, String> {
    pooled_ranges(view, layout, scan, view.settings.beam_pooling)
}

/// [`measured_ranges`] with `pooling`; each range's σ holds the frame's
/// scale error besides its own noise (docs/math.md §4.5): pooling averages
/// the beams' own noise, not the scale they share, so the scale is added
/// after it.
fn pooled_ranges(
    view: &MapperView,
    layout: &BeamLayout,
    scan: &Scan,
    pooling: Pooling,
) -> Result<Vec<Pooled>, String> {
    let mut pooled = own_noise_ranges(view, layout, scan, pooling)?;
    for p in pooled.iter_mut().flatten() {
        p.sigma = view.range.with_frame_scale(p.sigma, p.range);
    }
    Ok(pooled)
}

/// [`pooled_ranges`] with each range's own noise alone.
fn own_noise_ranges(
    view: &MapperView,
    layout: &BeamLayout,
    scan: &Scan,
    pooling: Pooling,
) -> Result<Vec<Pooled>, String> {
    let ranges: Vec<Option<f64>> = scan.measurements.iter().map(hit_range).collect();
    let pool = |columns: usize, directions: &[Vector3], ranges: &[Option<f64>]| {
        pool_ranges(
            pooling,
            columns,
            directions,
            ranges,
            |d, r| view.range.sigma(d, r),
            view.range.angular_sigma,
        )
    };
    if let [grid] = &layout.grids[..] {
        if grid.members.is_none() || pooling == Pooling::Off {
            return Ok(pool(grid.azimuth.count, &layout.directions, &ranges));
        }
    }
    let raw = pool(1, &layout.directions, &ranges);
    if pooling == Pooling::Off {
        return Ok(raw);
    }
    // An image's points pool with their neighbours on its pixels, other
    // clouds' on each grid's raster of bins.
    let rasters: Vec<((usize, usize), Vec<GridMember>)> = match &layout.pixels {
        Some(pixels) => vec![((pixels.columns, pixels.rows), pixels.members())],
        None => layout
            .grids
            .iter()
            .map(|grid| {
                (
                    (grid.azimuth.count, grid.elevation.count),
                    grid.slots(layout),
                )
            })
            .collect(),
    };
    let (mut out, rays) = (raw, (&layout.directions[..], &ranges[..]));
    for (k, (raster, members)) in rasters.into_iter().enumerate() {
        pool_on_raster(raster, &members, rays, &mut out, pool).map_err(|()| {
            match layout.pixels {
                Some(_) => format!("scan {} has two points on one pixel", scan.viewpoint),
                None => format!(
                    "beam pooling needs a regular raster, one point per angular bin: scan {} has \
                 two points in one bin of {:.4} deg; give the scanner's angular step, or map \
                 without beam pooling",
                    scan.viewpoint,
                    layout.grids[k].azimuth.step.to_degrees()
                ),
            }
        })?;
    }
    Ok(out)
}

/// Pools the beams `members` laid into the slots of a raster of `(columns,
/// rows)` with `pool(columns, slot directions, slot ranges)`, writing each
/// member's result into `out`; fails if two share a slot.
fn pool_on_raster(
    (columns, rows): (usize, usize),
    members: &[GridMember],
    (directions, ranges): (&[Vector3], &[Option<f64>]),
    out: &mut [Pooled],
    pool: impl Fn(usize, &[Vector3], &[Option<f64>]) -> Vec<Pooled>,
) -> Result<(), ()> {
    let mut slot_ranges = vec![None; columns * rows];
    let mut slot_directions = vec![Vector3::zeros(); columns * rows];
    for member in members {
        // A slot's direction is set once it holds a beam.
        if slot_directions[member.slot] != Vector3::zeros() {
            return Err(());
        }
        slot_directions[member.slot] = directions[member.beam];
        slot_ranges[member.slot] = ranges[member.beam];
    }
    let pooled = pool(columns, &slot_directions, &slot_ranges);
    for member in members {
        out[member.beam] = pooled[member.slot];
    }
    Ok(())
}

/// Where the surface crosses the nominal line of the beam along the unit
/// camera-frame `d` that measured `p`, with the covariance a map draws its
/// chord and free space from (docs/math.md §5.4, §5.5): σ along the beam is
/// the raw range's or the fitted plane's prediction σ, without the slide of
/// a turned beam along a slanted plane, which is where the beam hit and not
/// where the surface meets the line the map draws.
pub fn surface_point(range: &RangeModel, d: &Vector3, p: &PooledRange) -> UncertainPoint {
    camera_point(range, d, p.range, p.sigma)
}

/// Where the beam along `d` that measured `p` hit the surface, with its
/// covariance: a pooled range's holds the slide (docs/math.md §5.5). What
/// the run's NEES checks against the true hit.
pub fn hit_point(range: &RangeModel, d: &Vector3, p: &PooledRange) -> UncertainPoint {
    match p.covariance(d, range.angular_sigma) {
        Some(covariance) => UncertainPoint {
            mean: d * p.range,
            covariance,
        },
        None => surface_point(range, d, p),
    }
}

/// A hit's measured point from its raw range (see [`measured_ranges`]).
pub(crate) fn raw_point(view: &MapperView, m: &Measurement, d: &Vector3) -> Option<UncertainPoint> {
    hit_range(m).map(|r| {
        let sigma = view.range.with_frame_scale(view.range.sigma(d, r), r);
        camera_point(&view.range, d, r, sigma)
    })
}

/// The camera-frame point at range `r` along `d`, range noise `sigma`.
fn camera_point(range: &RangeModel, d: &Vector3, r: f64, sigma: f64) -> UncertainPoint {
    UncertainPoint {
        mean: d * r,
        covariance: range.point_covariance_with(d, r, sigma),
    }
}

/// The nominal origin, measured end points and no-return directions of a
/// scan, in the scene frame (what OctoMap's `insertPointCloud` is given: a
/// point recorded beyond the maximum range is an end point the update
/// truncates, as OctoMap's).
pub fn ray_inputs(layout: &BeamLayout, scan: &Scan) -> (Point3, Vec<Point3>, Vec<Vector3>) {
    let (mut hits, mut misses) = (Vec::new(), Vec::new());
    let origin = ray_inputs_into(layout, scan, None, &mut hits, &mut misses);
    (origin, hits, misses)
}

/// Where a scan's rays end for the ray update: with its pooling
/// (`MapSettings::ray_pooling`), at the pooled ranges; `None` without (the
/// raw hits, as OctoMap's).
pub fn pooled_ray_ends(
    view: &MapperView,
    layout: &BeamLayout,
    scan: &Scan,
) -> Result<Option<Vec<Pooled>>, String> {
    match view.settings.ray_pooling {
        Pooling::Off => Ok(None),
        pooling => pooled_ranges(view, layout, scan, pooling).map(Some),
    }
}

/// [`ray_inputs`] into buffers of the caller's (reused from scan to scan:
/// fresh ones cost a page fault every 4 KiB); with `points` (the scan's
/// [`measured_ranges`], pooled), each hit ends at its measured range.
pub fn ray_inputs_into(
    layout: &BeamLayout,
    scan: &Scan,
    points: Option<&[Pooled]>,
    hits: &mut Vec<Point3>,
    misses: &mut Vec<Vector3>,
) -> Point3 {
    let pose = scan.chain.scene_from_camera();
    hits.clear();
    misses.clear();
    for (k, (m, d)) in scan.measurements.iter().zip(&layout.directions).enumerate() {
        match m.status {
            BeamStatus::Hit => {
                let local = points
                    .and_then(|points| points[k].as_ref())
                    .map_or_else(|| d * m.range, |p| d * p.range);
                hits.push(pose * Point3::from(local));
            }
            BeamStatus::NoReturn if m.range.is_finite() => {
                hits.push(pose * Point3::from(d * m.range));
            }
            BeamStatus::NoReturn => misses.push(pose.rotation * d),
            _ => {}
        }
    }
    Point3::from(pose.translation.vector)
}
