//! OctoMap's arithmetic on the rays it is given: `float` points (`point3d`),
//! `float` norms, a ray cut at the maximum range in `float`, cell centres
//! (`OcTreeBaseImpl::keyToCoord`, `OccupancyOcTreeBase::computeUpdate`; the
//! keys are [`Octree::key`](super::super::octree::Octree::key)'s, OctoMap's
//! `coordToKey`). Here, in one place, so that the
//! ray update's cells are OctoMap's to the bit: a `double` walk differs from
//! OctoMap's where a ray crosses two cell borders at nearly the same point,
//! or starts on a cell border (a sensor at a round coordinate).

use super::super::octree::CENTER;
use crate::geometry::Point3;

/// `p` as the `float` point OctoMap holds (each coordinate rounded to the
/// nearest `f32`), in `f64`.
#[inline(always)]
pub(super) fn point(p: &Point3) -> Point3 {
    p.map(|c| f64::from(c as f32))
}

/// OctoMap's `keyToCoord` of one coordinate of a finest key: the cell's
/// centre, `(k − 2¹⁵ + ½) · res`, in `double`.
#[inline(always)]
pub(super) fn centre(key: u16, res: f64) -> f64 {
    ((key as i64 - CENTER) as f64 + 0.5) * res
}

/// OctoMap's `point3d::norm` of a `float` vector: the `float` sum of the
/// `float` squares, its root in `double`.
#[inline(always)]
pub(super) fn norm(d: &nalgebra::Vector3<f32>) -> f64 {
    f64::from(d.x * d.x + d.y * d.y + d.z * d.z).sqrt()
}

/// OctoMap's `computeUpdate` for the `float` point `p` seen from the
/// `float` point `origin`: `None` when `‖p − origin‖ ≤ max_range` (a hit),
/// else the end of the ray cut at the maximum range, `origin + (p −
/// origin)/‖p − origin‖ · max_range`, in OctoMap's `float` operations. The
/// maximum range is the `float` the rays' file holds.
#[inline(always)]
pub(super) fn cut(origin: &Point3, p: &Point3, max_range: f64) -> Option<Point3> {
    let (o, p) = (origin.map(|c| c as f32), p.map(|c| c as f32));
    let max_range = max_range as f32;
    let d = p - o;
    let norm = norm(&d);
    if norm <= f64::from(max_range) {
        return None;
    }
    let direction: nalgebra::Vector3<f32> = d / norm as f32;
    Some((o + direction * max_range).map(f64::from))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ray_beyond_the_maximum_range_is_cut_in_octomaps_float_operations() {
        // OctoMap: `direction = (p − origin).normalized()` (each `float`
        // component over the `float` of the `double` norm), then `origin +
        // direction · (float) maxrange`, all in `float`.
        let origin = [0.013f32, -0.031, 0.257];
        let mut rounded_otherwise = 0;
        for i in 0..500 {
            let t = i as f32;
            let p = [1.5 + t * 0.037, -2.0 + t * 0.011, 3.0 - t * 0.005];
            let d: [f32; 3] = std::array::from_fn(|k| p[k] - origin[k]);
            let norm = f64::from(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let direction = d.map(|c| c / norm as f32);
            let octomap: [f32; 3] = std::array::from_fn(|k| origin[k] + direction[k] * 2.0);
            assert_eq!(
                cut(&as_point(origin), &as_point(p), 2.0),
                Some(as_point(octomap))
            );
            let exact: [f32; 3] = std::array::from_fn(|k| {
                (f64::from(origin[k]) + f64::from(d[k]) / norm * 2.0) as f32
            });
            rounded_otherwise += usize::from(exact != octomap);
        }
        // The float operations matter: the end cells of such rays follow.
        assert!(rounded_otherwise > 50, "{rounded_otherwise}");
        let near = Point3::new(1.0, 1.0, 1.0);
        assert_eq!(cut(&as_point(origin), &near, 2.0), None);
    }

    fn as_point(v: [f32; 3]) -> Point3 {
        Point3::from(v.map(f64::from))
    }
}
