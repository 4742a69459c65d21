//! Pooling a whole planar face (docs/math.md §5.5, "faces").
//!
//! A 3×3 window fixes a surface to about σ/3, which leaves a large face
//! that lies a fraction of a millimetre below a cell plane to chance. A
//! face seen by thousands of beams fixes its plane to σ/√m. Faces are grown
//! over the beams whose window was pooled, each against the plane of what
//! it has grown so far; a face whose hits pass a χ² test as one plane pools
//! the beams in its interior on that plane (its members, and the hits on it
//! whose own window failed by chance).

use super::{fit_plane, Neighbour, Plane, Pooled};
use crate::geometry::Vector3;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Hits a face needs before its plane replaces the windows'. [DESIGN]
/// Measured (§5.5): letting faces of 10 or 50 hits pool raised ANEES
/// (3.47–3.50 against 3.38) without changing the maps; from 200 to 2 000
/// the maps are the same (table tops and box faces reach it).
pub(super) const MIN_FACE_HITS: usize = 200;

/// A beam joins a face when its window's estimate lies within this many of
/// that estimate's standard deviations of the face's plane (as a beam must
/// lie within 3σ of its own window's plane to be pooled there): a step of a
/// few σ/3, a plate lying on a table, is not taken into the table.
const JOIN_SIGMAS: f64 = 3.0;

/// Most times a grown face is refitted and its refused neighbours asked
/// again. Measured on `paper.toml`: at most 20 rounds, on faces of about a
/// hundred hits (too small to pool); the cap only bounds the work of a face
/// that keeps creeping along a curved surface.
const MAX_ROUNDS: usize = 32;

/// Raises `out` (the windows' pooling of the `hits`, beams row by row with
/// `columns` per row) to the face's plane for every beam inside a planar
/// face of at least [`MIN_FACE_HITS`] hits, and for the hits beside it on
/// its plane whose window failed by chance. Returns which beams it raised.
pub(super) fn pool_faces(
    columns: usize,
    directions: &[Vector3],
    hits: &[Option<Neighbour>],
    out: &mut [Pooled],
) -> Vec<bool> {
    let mut raised = vec![false; out.len()];
    if columns == 0 {
        return raised;
    }
    // Whole raster rows only.
    let rows = hits.len().min(out.len()).min(directions.len()) / columns;
    let count = rows * columns;
    if count < MIN_FACE_HITS {
        return raised;
    }
    let raster = Raster {
        columns,
        rows,
        directions,
        hits,
        // Only a beam whose own window was one plane plus noise may seed or
        // join a face: an edge or a second surface in its window refused it.
        window_pooled: out[..count]
            .iter()
            .map(|p| p.is_some_and(|p| p.normal.is_some()))
            .collect(),
    };
    let (face_of, faces) = raster.grow_faces(out);
    // The strays taken by the face at hand (cleared after each face).
    let mut taken = vec![false; count];
    for (id, face) in faces.iter().enumerate() {
        let Some(test) = raster.planar(face) else {
            continue;
        };
        let on_face = |j: usize| raster.on_face(j, id as u32, &face_of, &test.plane);
        // The hits beside the face whose window failed by chance (one in a
        // hundred at the 99% test) and that lie on its plane: where a window
        // failed for a real second surface, a neighbour shows it and the rim
        // rule below keeps the hit out.
        let mut stray = Vec::new();
        for &k in face {
            for j in beside(k, (columns, rows)).into_iter().flatten() {
                if !taken[j] && !raster.windowed(j) && raster.hit(j).is_some() && on_face(j) {
                    taken[j] = true;
                    stray.push(j);
                }
            }
        }
        for &k in face.iter().chain(&stray) {
            if !raster.inside(k, &on_face) || test.plane.normal.dot(&directions[k]).abs() < 0.1 {
                continue;
            }
            if let Some(pooled) = test
                .plane
                .predict(&directions[k], test.mean_variance, test.m)
            {
                out[k] = Some(pooled);
                raised[k] = true;
            }
        }
        for &j in &stray {
            taken[j] = false;
        }
    }
    raised
}

/// A face that passed the test of one plane: its plane, the mean variance
/// of its hits along the normal, and how many hits it has.
struct PlanarFace {
    plane: Plane,
    mean_variance: f64,
    m: f64,
}

/// A scan's raster of beams as faces see it.
struct Raster<'a> {
    columns: usize,
    rows: usize,
    directions: &'a [Vector3],
    hits: &'a [Option<Neighbour>],
    /// Whether each beam's own window was pooled as one plane.
    window_pooled: Vec<bool>,
}

impl Raster<'_> {
    fn hit(&self, k: usize) -> Option<Vector3> {
        self.hits[k].map(|h| h.point)
    }

    fn fit(&self, face: &[usize]) -> Option<Plane> {
        fit_plane(face.iter().filter_map(|&k| self.hits[k].as_ref()))
    }

    fn variance_along(&self, k: usize, normal: &Vector3) -> f64 {
        self.hits[k].map_or(0.0, |h| h.normal_variance(normal))
    }

    fn windowed(&self, k: usize) -> bool {
        self.window_pooled[k]
    }

    /// Every face grown from the windows of `out`: which face each beam is
    /// in (`u32::MAX`: none) and each face's beams.
    fn grow_faces(&self, out: &[Pooled]) -> (Vec<u32>, Vec<Vec<usize>>) {
        let count = self.window_pooled.len();
        let directions = self.directions;
        // Whether beam j's window estimate lies within JOIN_SIGMAS of its
        // own standard deviation (along the normal) of the plane through
        // `centre`.
        let window_near = |j: usize, normal: &Vector3, centre: &Vector3| {
            out[j].is_some_and(|w| {
                let distance = normal.dot(&(directions[j] * w.range - centre));
                distance.abs() <= JOIN_SIGMAS * w.sigma * normal.dot(&directions[j]).abs()
            })
        };
        let fit = |face: &[usize]| self.fit(face);
        let mut face_of = vec![u32::MAX; count];
        let mut faces: Vec<Vec<usize>> = Vec::new();
        for seed in 0..count {
            if face_of[seed] != u32::MAX || !self.windowed(seed) {
                continue;
            }
            let id = faces.len() as u32;
            let Some(window) = out[seed] else { continue };
            // The seed's window plane: through its pooled point, its normal.
            let plane = (
                directions[seed] * window.range,
                window.normal.unwrap_or_default(),
            );
            let mut claim = |k: usize| {
                let free = face_of[k] == u32::MAX && self.windowed(k);
                if free {
                    face_of[k] = id;
                }
                free
            };
            let raster = (self.columns, self.rows);
            let face = grow(seed, plane, raster, &window_near, &mut claim, &fit);
            faces.push(face);
        }
        (face_of, faces)
    }

    /// The face's plane if the face is large enough and its hits pass the
    /// 99% χ² test of one plane plus noise.
    fn planar(&self, face: &[usize]) -> Option<PlanarFace> {
        if face.len() < MIN_FACE_HITS {
            return None;
        }
        let plane = self.fit(face)?;
        let variances: Vec<f64> = face
            .iter()
            .map(|&k| self.variance_along(k, &plane.normal))
            .collect();
        let chi2: f64 = face
            .iter()
            .zip(&variances)
            .map(|(&k, v)| self.hit(k).map_or(0.0, |h| plane.distance(&h).powi(2) / v))
            .sum();
        let chi = ChiSquared::new((face.len() - 3) as f64).ok()?;
        if chi2 > chi.inverse_cdf(0.99) {
            return None;
        }
        let m = face.len() as f64;
        let mean_variance = variances.iter().sum::<f64>() / m;
        Some(PlanarFace {
            plane,
            mean_variance,
            m,
        })
    }

    /// Whether beam `j` shows no other surface than face `id` on `plane`:
    /// a member, a hit whose window failed its test (by chance, one in a few
    /// dozen) and which lies within 3σ of the plane, or a beam without a
    /// return (nothing in range, or one of the sensor's dropouts). A hit
    /// whose window passed but did not join lies on another surface, as
    /// does a failed hit off the plane.
    fn on_face(&self, j: usize, id: u32, face_of: &[u32], plane: &Plane) -> bool {
        face_of[j] == id
            || self.hit(j).is_none_or(|h| {
                !self.windowed(j)
                    && plane.distance(&h).powi(2)
                        <= JOIN_SIGMAS * JOIN_SIGMAS * self.variance_along(j, &plane.normal)
            })
    }

    /// Whether beam `k` lies inside its face. A hit on the face's rim may
    /// belong to the next surface (the foot of an object standing on a
    /// table lies within 3σ of the table): only beams with eight neighbours,
    /// none showing another surface (`on_face`), are pooled on it. Past the
    /// raster's edge nothing is known, and a surface there may rise from the
    /// face: measured (§5.5), pooling the edge too raised the shelf's ANEES.
    fn inside(&self, k: usize, on_face: &impl Fn(usize) -> bool) -> bool {
        let (columns, rows) = (self.columns, self.rows);
        let (row, col) = (k / columns, k % columns);
        row > 0
            && col > 0
            && row + 1 < rows
            && col + 1 < columns
            && (row - 1..=row + 1).all(|r| (col - 1..=col + 1).all(|c| on_face(r * columns + c)))
    }
}

/// The face grown from beam `seed`: breadth first over the four raster
/// neighbours (`(columns, rows)`), a neighbour joining when it is `near`
/// the plane of the face so far (`(point, normal)` first: the seed's window
/// plane; refitted each time the face doubles, and to the whole face once
/// it stops growing, when the neighbours refused are asked again) and
/// `claim` gives it (unassigned, its window pooled).
fn grow(
    seed: usize,
    (mut centre, mut normal): (Vector3, Vector3),
    (columns, rows): (usize, usize),
    near: &impl Fn(usize, &Vector3, &Vector3) -> bool,
    claim: &mut impl FnMut(usize) -> bool,
    fit: &impl Fn(&[usize]) -> Option<Plane>,
) -> Vec<usize> {
    let mut face = Vec::new();
    if !claim(seed) {
        return face;
    }
    face.push(seed);
    let refit = |face: &[usize], normal: &mut Vector3, centre: &mut Vector3| {
        if let Some(plane) = fit(face) {
            (*normal, *centre) = (plane.normal, plane.centroid);
        }
    };
    // Neighbours refused so far: an early plane, fitted to a few dozen hits,
    // may refuse beams far along the face that the final plane takes.
    let mut refused = Vec::new();
    let (mut next_fit, mut head, mut rounds) = (16, 0, 0);
    loop {
        while head < face.len() {
            let k = face[head];
            head += 1;
            for j in beside(k, (columns, rows)).into_iter().flatten() {
                if !near(j, &normal, &centre) {
                    refused.push(j);
                } else if claim(j) {
                    face.push(j);
                }
            }
            if face.len() >= next_fit {
                refit(&face, &mut normal, &mut centre);
                next_fit *= 2;
            }
        }
        // Grown as far as this plane allows: refit to the whole face and ask
        // the refused again, until none joins.
        refit(&face, &mut normal, &mut centre);
        let before = face.len();
        for j in std::mem::take(&mut refused) {
            if !near(j, &normal, &centre) {
                refused.push(j);
            } else if claim(j) {
                face.push(j);
            }
        }
        rounds += 1;
        if face.len() == before || rounds == MAX_ROUNDS {
            break;
        }
    }
    face
}

/// The four raster neighbours of beam `k` (`(columns, rows)`), those that
/// exist.
fn beside(k: usize, (columns, rows): (usize, usize)) -> [Option<usize>; 4] {
    let (row, col) = (k / columns, k % columns);
    [
        (col + 1 < columns).then(|| k + 1),
        (col > 0).then(|| k - 1),
        (row + 1 < rows).then(|| k + columns),
        (row > 0).then(|| k - columns),
    ]
}
