//! Pooling a viewpoint's beams on the surface they share (docs/math.md §5.5).
//!
//! The range noise of neighbouring beams is independent while the surface
//! they hit is (locally) one plane: a least-squares plane through a beam's
//! 3×3 raster neighbourhood estimates where the beam's line meets the
//! surface with variance ≈ σ²/n instead of σ², when the neighbourhood is one
//! plane plus noise. A beam whose own range disagrees with the plane (an
//! edge, a second surface) keeps its measurement. A large planar face is
//! then pooled whole (`faces`): thousands of hits fix its plane to
//! hundredths of a millimetre.

use crate::geometry::{Matrix3, Vector3};
use rayon::prelude::*;

/// A beam's pooled range, its standard deviation (m) and the normal of the
/// plane it was pooled on (`None`: the raw range was kept).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PooledRange {
    /// Where the beam's line meets the surface (m).
    pub range: f64,
    /// The standard deviation of `range` (m): the range noise of a raw
    /// range, the fitted plane's prediction σ where it crosses the beam's
    /// nominal line for a pooled one (what a map draws, §5.5; where the
    /// turned beam hit is [`PooledRange::covariance`]).
    pub sigma: f64,
    /// The unit normal of the fitted plane, if pooled.
    pub normal: Option<Vector3>,
}

/// A beam's [`PooledRange`], or `None` for a beam without a hit.
pub type Pooled = Option<PooledRange>;

/// Which beams a viewpoint pools (docs/math.md §5.5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Pooling {
    /// None: every hit keeps its measured range.
    #[default]
    Off,
    /// Only the beams inside a large planar face, on the face's plane; the
    /// windows serve to grow the faces and are not kept. The faces'
    /// covariances are honest; the windows' are not on curved objects.
    Faces,
    /// Every beam whose 3×3 window is one plane, and the faces.
    Windows,
}

impl Pooling {
    /// The mode named `off`, `faces` or `windows` (experiment files and
    /// `--beam-pooling`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "off" => Some(Self::Off),
            "faces" => Some(Self::Faces),
            "windows" => Some(Self::Windows),
            _ => None,
        }
    }

    /// Its name in experiment files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Off => "off",
            Self::Faces => "faces",
            Self::Windows => "windows",
        }
    }
}

/// Pools the hits of one viewpoint, on each beam's 3×3 window, then on the
/// large planar faces grown over those windows (with [`Pooling::Faces`],
/// only the faces' beams keep a pooled range). `ranges[k]` is beam k's
/// measured range (`None`: no hit), `directions[k]` its unit direction,
/// beams row by row with `columns` per row; `sigma(d, r)` is the range
/// noise of the beam along `d` at range r and `angular_sigma` the beams' direction noise (rad).
pub fn pool_ranges(
    pooling: Pooling,
    columns: usize,
    directions: &[Vector3],
    ranges: &[Option<f64>],
    sigma: impl Fn(&Vector3, f64) -> f64 + Sync,
    angular_sigma: f64,
) -> Vec<Pooled> {
    let raw = |k: usize| {
        ranges[k].map(|r| PooledRange {
            range: r,
            sigma: sigma(&directions[k], r),
            normal: None,
        })
    };
    if pooling == Pooling::Off {
        return (0..ranges.len()).map(raw).collect();
    }
    let rows = ranges.len() / columns.max(1);
    // Each hit's point and noise, once: a hit sits in up to nine windows.
    let hits: Vec<Option<Neighbour>> = ranges
        .par_iter()
        .zip(directions)
        .map(|(r, d)| r.map(|r| Neighbour::new(d, r, sigma(d, r), r * angular_sigma)))
        .collect();
    // The windows are independent of each other: spread over the threads,
    // collected in beam order (the same result on any number of threads).
    let mut out: Vec<Pooled> = (0..ranges.len())
        .into_par_iter()
        .with_min_len(columns.max(1))
        .map_init(
            || Vec::with_capacity(9),
            |points, k| pool_window(&hits, ranges, (columns, rows), points, k),
        )
        .collect();
    let on_faces = faces::pool_faces(columns, directions, &hits, &mut out);
    if pooling == Pooling::Faces {
        for (k, slot) in out.iter_mut().enumerate() {
            if !on_faces[k] {
                *slot = raw(k);
            }
        }
    }
    out
}

/// Beam `k`'s [`pool_one`] on its 3×3 raster window of `hits`
/// (`(columns, rows)`; `points`: a buffer for the window).
fn pool_window<'h>(
    hits: &'h [Option<Neighbour>],
    ranges: &[Option<f64>],
    (columns, rows): (usize, usize),
    points: &mut Vec<&'h Neighbour>,
    k: usize,
) -> Pooled {
    let own = hits[k].as_ref()?;
    let (row, col) = ((k / columns) as i64, (k % columns) as i64);
    points.clear();
    for dr in -1..=1i64 {
        for dc in -1..=1i64 {
            let (rr, cc) = (row + dr, col + dc);
            if rr < 0 || cc < 0 || rr >= rows as i64 || cc >= columns as i64 {
                continue;
            }
            points.extend(&hits[rr as usize * columns + cc as usize]);
        }
    }
    let r = ranges[k].unwrap_or_default();
    Some(pool_one(points, &own.direction, r, own.sigma))
}

/// The variance along the plane normal `normal` of a hit along `direction`
/// with range noise `sigma` and sideways noise `lateral` (`r σ_a`): its range
/// noise seen along the normal, and its direction noise moving it sideways,
/// off a slanted plane.
#[inline]
fn normal_variance(normal: &Vector3, direction: &Vector3, sigma: f64, lateral: f64) -> f64 {
    let along = normal.dot(direction);
    (sigma * along).powi(2) + lateral.powi(2) * (1.0 - along * along).max(0.0)
}

impl PooledRange {
    /// The camera-frame covariance of a pooled beam's point `d · range` as an
    /// estimate of where the beam, drawn off `d` by its direction noise
    /// `angular_sigma`, met the surface (§5.5); `None` for a raw range (the
    /// sensor's `σ² d dᵀ + r² σ_a² (I − d dᵀ)`). On a plane with normal n the
    /// beam's true hit slides along the plane, `r P δ` with
    /// `P = I − d nᵀ / (n·d)`, so the lateral term becomes
    /// `r² σ_a² P (I − d dᵀ) Pᵀ`: a slanted plane turns direction noise into
    /// range error (`r σ_a tan θ` along the beam), which the raw range
    /// already holds and the plane's prediction does not. The run's NEES
    /// checks this covariance; a map draws `sigma` alone along the beam.
    pub fn covariance(&self, d: &Vector3, angular_sigma: f64) -> Option<Matrix3> {
        let n = self.normal?;
        let ddt = d * d.transpose();
        let slide = Matrix3::identity() - d * n.transpose() / n.dot(d);
        let lateral = slide * (Matrix3::identity() - ddt) * slide.transpose();
        let r = self.range;
        Some(ddt * (self.sigma * self.sigma) + lateral * (r * r * angular_sigma * angular_sigma))
    }
}

/// χ² 99% quantiles for 1–6 degrees of freedom: a neighbourhood is one
/// plane plus noise only if its residuals pass this test.
const CHI2_99: [f64; 6] = [6.635, 9.210, 11.345, 13.277, 15.086, 16.812];

/// The pooled range of a beam along `direction` measured at `r` (range
/// noise `sigma`), from the points of its neighbourhood (itself included).
/// Only a neighbourhood that is one plane plus noise (χ² test of the
/// residuals at 99%, at least 5 points) is pooled; anything else (an edge, a
/// second surface, a corner) keeps the raw range. Dropping points until the
/// test passes would bias the variance; refusing does not.
fn pool_one(points: &[&Neighbour], direction: &Vector3, r: f64, sigma: f64) -> PooledRange {
    let raw = PooledRange {
        range: r,
        sigma,
        normal: None,
    };
    let Some((plane, variances)) = one_plane(points) else {
        return raw;
    };
    let variances = &variances[..points.len()];
    let along = plane.normal.dot(direction);
    let own_off = plane.distance(&(direction * r)) / (sigma * along.abs().max(1e-3));
    if own_off.abs() > 3.0 || along.abs() < 0.1 {
        return raw;
    }
    let n = points.len() as f64;
    let mean_variance = variances.iter().sum::<f64>() / n;
    plane.predict(direction, mean_variance, n).unwrap_or(raw)
}

/// The plane of 5 to 9 `points` if they are one plane plus noise (the χ²
/// test of their residuals at 99%), with each point's noise variance along
/// its normal; `None` otherwise.
fn one_plane(points: &[&Neighbour]) -> Option<(Plane, [f64; 9])> {
    if !(5..=9).contains(&points.len()) {
        return None;
    }
    let plane = fit_plane(points.iter().copied())?;
    let mut variances = [0.0; 9];
    for (v, p) in variances.iter_mut().zip(points) {
        *v = p.normal_variance(&plane.normal);
    }
    let chi2: f64 = points
        .iter()
        .zip(&variances)
        .map(|(p, v)| plane.distance(&p.point).powi(2) / v.max((1e-3 * p.sigma).powi(2)))
        .sum();
    (chi2 <= CHI2_99[points.len() - 4]).then_some((plane, variances))
}

/// Whether 5 to 9 hits, each `(direction, range, σ, lateral)` (a unit
/// direction from one origin, the range noise along it and the sideways
/// noise), are one plane plus noise: the windows' test (docs/math.md §5.5),
/// here on a local grid's beams.
pub(crate) fn hits_on_one_plane(hits: &[(Vector3, f64, f64, f64)]) -> bool {
    if hits.len() > 9 {
        return false;
    }
    let mut neighbours = [Neighbour::new(&Vector3::x(), 0.0, 0.0, 0.0); 9];
    for (slot, (d, r, sigma, lateral)) in neighbours.iter_mut().zip(hits) {
        *slot = Neighbour::new(d, *r, *sigma, *lateral);
    }
    let refs: [&Neighbour; 9] = std::array::from_fn(|i| &neighbours[i]);
    one_plane(&refs[..hits.len()]).is_some()
}

/// A hit of the neighbourhood: its camera-frame point, range noise, the
/// sideways noise its direction noise gives it at its range (`r σ_a`), its
/// beam direction and the point's covariance.
#[derive(Clone, Copy)]
struct Neighbour {
    point: Vector3,
    sigma: f64,
    lateral: f64,
    direction: Vector3,
    covariance: Matrix3,
}

impl Neighbour {
    /// The hit at range `r` along unit `direction` with range noise `sigma`
    /// and sideways noise `lateral`: covariance `σ² d dᵀ + lateral² (I − d dᵀ)`.
    fn new(direction: &Vector3, r: f64, sigma: f64, lateral: f64) -> Self {
        let ddt = direction * direction.transpose();
        Self {
            point: direction * r,
            sigma,
            lateral,
            direction: *direction,
            covariance: ddt * (sigma * sigma) + (Matrix3::identity() - ddt) * (lateral * lateral),
        }
    }

    /// Its noise variance along the unit `normal` ([`normal_variance`]).
    fn normal_variance(&self, normal: &Vector3) -> f64 {
        normal_variance(normal, &self.direction, self.sigma, self.lateral)
    }
}

struct Plane {
    centroid: Vector3,
    normal: Vector3,
    /// The two in-plane axes and the points' scatter along each.
    in_plane: [(Vector3, f64); 2],
}

impl Plane {
    fn distance(&self, p: &Vector3) -> f64 {
        self.normal.dot(&(p - self.centroid))
    }

    /// Where the line along `direction` meets the plane fitted to `n` points
    /// whose mean variance along the normal is `mean_variance`, with the
    /// regression prediction variance there (along the normal, then along
    /// the beam): `σ̄_n² (1/n + (o·u)²/λ_u + (o·v)²/λ_v) / (n·d)²`. `None`
    /// when the line meets it behind the sensor or not at all.
    fn predict(&self, direction: &Vector3, mean_variance: f64, n: f64) -> Option<PooledRange> {
        let along = self.normal.dot(direction);
        let pooled = self.normal.dot(&self.centroid) / along;
        if !(pooled.is_finite() && pooled > 0.0) {
            return None;
        }
        let offset = direction * pooled - self.centroid;
        let spread = self
            .in_plane
            .iter()
            .map(|(axis, scatter)| offset.dot(axis).powi(2) / scatter)
            .sum::<f64>();
        let variance = mean_variance * (1.0 / n + spread) / (along * along);
        Some(PooledRange {
            range: pooled,
            sigma: variance.sqrt(),
            normal: Some(self.normal),
        })
    }
}

/// The plane of ≥ 4 hits (`None` when they are degenerate: all on a
/// line), from their points' scatter less the scatter their noise adds:
/// `S − (m − 1)/m · Σ_j C_j`, `C_j` the hits' covariances. Range noise lies along each beam, not along the normal, and
/// on a slanted plane it tilts the plain total-least-squares plane: a face's
/// prediction at a beam off its centroid was then biased by half its σ
/// (docs/math.md §5.5); removing the noise's share makes the fit consistent.
fn fit_plane<'a>(hits: impl Iterator<Item = &'a Neighbour> + Clone) -> Option<Plane> {
    // The count, the noise and the points' sum in one pass (a face's hits
    // are scattered in memory), the scatter about their centroid in another.
    let (n, noise, sum) = hits.clone().fold(
        (0usize, Matrix3::zeros(), Vector3::zeros()),
        |(n, noise, sum), h| (n + 1, noise + h.covariance, sum + h.point),
    );
    if n < 4 {
        return None;
    }
    let centroid = sum / n as f64;
    let scatter = hits.fold(Matrix3::zeros(), |a, h| {
        let d = h.point - centroid;
        a + d * d.transpose()
    }) - noise * ((n - 1) as f64 / n as f64);
    let (eigenvalues, eigenvectors) = crate::geometry::symmetric_eigen(&scatter);
    let (mut min, mut second) = (0, 1);
    for i in 0..3 {
        if eigenvalues[i] < eigenvalues[min] {
            min = i;
        }
    }
    for i in 0..3 {
        if i != min && (second == min || eigenvalues[i] < eigenvalues[second]) {
            second = i;
        }
    }
    // A line of points (second-smallest spread ~0) does not fix a plane.
    if eigenvalues[second] <= 1e-12 {
        return None;
    }
    let third = 3 - min - second;
    let axis = |i: usize| (eigenvectors.column(i).into_owned(), eigenvalues[i]);
    Some(Plane {
        centroid,
        normal: eigenvectors.column(min).into_owned(),
        in_plane: [axis(second), axis(third)],
    })
}

mod faces;
#[cfg(test)]
mod tests;
