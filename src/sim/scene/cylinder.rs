//! The closed-form ray cast on a solid cylinder. parry casts rays on
//! cylinders by GJK, several times slower than the quadratic for the side
//! and the two caps; the scene uses this one for every cylinder object
//! (a test checks it against parry).

use parry3d_f64::math::Vector as ParryVector;

/// First entry of the ray `o + t d` (t in `[0, max]`) into the closed solid
/// cylinder `x² + z² <= r²`, `|y| <= h` (parry's local cylinder frame); 0 when
/// `o` is inside.
pub(super) fn cast_cylinder(
    radius: f64,
    half_height: f64,
    o: ParryVector,
    d: ParryVector,
    max: f64,
) -> Option<f64> {
    let r2 = radius * radius;
    let radial = |t: f64| (o.x + t * d.x).powi(2) + (o.z + t * d.z).powi(2);
    if o.y.abs() <= half_height && radial(0.0) <= r2 {
        return Some(0.0);
    }
    let mut best = f64::INFINITY;
    let a = d.x * d.x + d.z * d.z;
    if a > 0.0 {
        let b = o.x * d.x + o.z * d.z;
        let disc = b * b - a * (o.x * o.x + o.z * o.z - r2);
        if disc >= 0.0 {
            let t = (-b - disc.sqrt()) / a;
            if t >= 0.0 && (o.y + t * d.y).abs() <= half_height {
                best = t;
            }
        }
    }
    if d.y != 0.0 {
        for cap in [-half_height, half_height] {
            let t = (cap - o.y) / d.y;
            if t >= 0.0 && t < best && radial(t) <= r2 {
                best = t;
            }
        }
    }
    (best <= max).then_some(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use parry3d_f64::query::Ray;

    #[test]
    fn analytic_cylinder_cast_agrees_with_parry() {
        use parry3d_f64::query::RayCast;
        use parry3d_f64::shape::Cylinder;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let cylinder = Cylinder::new(0.3, 0.1);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = ParryVector::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let target = ParryVector::new(
                rng.random_range(-0.15..0.15),
                rng.random_range(-0.4..0.4),
                rng.random_range(-0.15..0.15),
            );
            let d = (target - o).normalize();
            let ours = cast_cylinder(0.1, 0.3, o, d, 5.0);
            let theirs = cylinder.cast_local_ray(&Ray::new(o, d), 5.0, true);
            match (ours, theirs) {
                (Some(a), Some(b)) => {
                    hits += 1;
                    assert!((a - b).abs() < 1e-6, "{a} vs {b}");
                }
                (None, None) => {}
                // Grazing rays may differ within GJK's tolerance.
                (a, b) => {
                    let t = a.or(b).unwrap();
                    let p = o + d * t;
                    let rim = ((p.x * p.x + p.z * p.z).sqrt() - 0.1)
                        .abs()
                        .min((p.y.abs() - 0.3).abs());
                    assert!(rim < 1e-6, "{a:?} vs {b:?}");
                }
            }
        }
        assert!(hits > 500);
    }
}
