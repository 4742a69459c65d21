//! Bin lookups from the tangent of an angle, without computing the angle
//! (docs/math.md §5.1): the fastest of the three paths of [`super::lookup`].
//!
//! On an axis whose angles stay within ±[`MAX_ANGLE`], `tan` is increasing,
//! so an angle θ lies in bin k, clear of its edges by [`ANGLE_SLACK`], exactly
//! when `tan θ` lies strictly between `tan(edge_k + slack)` and
//! `tan(edge_{k+1} − slack)`, both tabulated once per grid. A direction's
//! tangents are ratios of its coordinates (`y/x`, `z/ρ`), and a ball's edge
//! angles `el ± β`, `az ± γ` have tangents by the addition formula, so no
//! `atan` is called. Whenever a tangent is not strictly inside one bin's
//! interval, or strictly beyond the axis, the lookup is undecided and the
//! caller asks the next path. The intervals leave [`ANGLE_SLACK`] on each side,
//! which dwarfs every rounding on the way (at most ~1e-14 rad), so a decided
//! answer is the `⌊(angle − start)/step⌋` of libm's angles, bit for bit
//! (tested against it in `lookup`).

use super::lookup::ANGLE_SLACK;
use super::Axis;

/// Axes reaching beyond this angle (rad, ~86°) get no table: near ±π/2 the
/// tangent grows without bound.
const MAX_ANGLE: f64 = 1.5;

/// Guess-table cells are kept below this many per axis (a grid of ~0.003°
/// bins over ±86° would need more); beyond it the axis gets no table.
const MAX_CELLS: usize = 1 << 16;

/// Tangent intervals of the bins of one axis, and a uniform table over the
/// tangent that guesses the bin of a value to within one.
#[derive(Clone, Debug, Default)]
pub(crate) struct TangentBins {
    /// `tan(start − slack)` and `tan(end + slack)`: beyond them an angle is
    /// surely off the axis.
    below: f64,
    above: f64,
    /// Per bin, the open interval of tangents surely inside it (empty: no
    /// table).
    clear: Vec<[f64; 2]>,
    /// `tan(start)`, and guess-table cells per unit of tangent.
    origin: f64,
    per_unit: f64,
    /// Per cell of the guess table, the bin holding the cell's lower end.
    guess: Vec<u32>,
}

impl TangentBins {
    /// The table of `axis`; an empty one (every lookup undecided) when the
    /// axis reaches beyond ±[`MAX_ANGLE`] or would need too large a table.
    pub(crate) fn new(axis: &Axis) -> Self {
        let (start, end) = (axis.start, axis.end());
        let usable = axis.count > 0
            && axis.step > 0.0
            && start - ANGLE_SLACK > -MAX_ANGLE
            && end + ANGLE_SLACK < MAX_ANGLE;
        if !usable {
            return Self::default();
        }
        let edge = |k: usize| (start + k as f64 * axis.step).tan();
        let edges: Vec<f64> = (0..=axis.count).map(edge).collect();
        let narrowest = edges
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        // Four cells per narrowest bin: a cell meets at most two bins, and
        // few cells meet two.
        let per_unit = 4.0 / narrowest;
        let span = edges[axis.count] - edges[0];
        let cells = (span * per_unit).ceil() + 1.0;
        if !(narrowest > 0.0 && cells.is_finite() && cells < MAX_CELLS as f64) {
            return Self::default();
        }
        let mut guess = Vec::with_capacity(cells as usize);
        let mut k = 0usize;
        for cell in 0..cells as usize {
            let low = edges[0] + cell as f64 / per_unit;
            while k + 1 < axis.count && edges[k + 1] <= low {
                k += 1;
            }
            guess.push(k as u32);
        }
        let clear = (0..axis.count)
            .map(|k| {
                let lower = start + k as f64 * axis.step;
                let upper = start + (k + 1) as f64 * axis.step;
                [(lower + ANGLE_SLACK).tan(), (upper - ANGLE_SLACK).tan()]
            })
            .collect();
        Self {
            below: (start - ANGLE_SLACK).tan(),
            above: (end + ANGLE_SLACK).tan(),
            clear,
            origin: edges[0],
            per_unit,
            guess,
        }
    }

    /// The bin of the angle whose tangent is `t`: `Some(k)` inside the axis,
    /// `Some(-1)` surely before it, `Some(count)` surely after it (the
    /// unclamped index compares to the axis alike), `None` when undecided
    /// (near an edge, no table, NaN).
    #[inline]
    pub(crate) fn locate(&self, t: f64) -> Option<isize> {
        if self.clear.is_empty() {
            return None;
        }
        if t < self.below {
            return Some(-1);
        }
        if t > self.above {
            return Some(self.clear.len() as isize);
        }
        // Saturating: a value just below `origin` (and NaN) takes cell 0,
        // whose intervals then reject it; one beyond the table, u32::MAX. (To
        // u32, not usize: x86 converts to a signed integer in one instruction,
        // to an unsigned 64-bit one in several.)
        let cell = ((t - self.origin) * self.per_unit) as u32;
        let guess = *self.guess.get(cell as usize)? as usize;
        // The guess or the next bin (a cell meets at most two), chosen
        // without a branch; a value within the slack of the edge between
        // them fails the check below either way.
        let bin = guess + usize::from(t >= self.clear[guess][1]);
        let [lo, hi] = *self.clear.get(bin)?;
        (t > lo && t < hi).then_some(bin as isize)
    }

    /// The bin `k` of the angle θ whose tangent is `t`, inside the axis, and
    /// a lower bound (rad) on θ's distance to the edges of bin k's clear
    /// interval `[lo, hi]`; `None` when [`TangentBins::locate`] is undecided
    /// or off the axis. No angle is computed: `atan` has slope
    /// `1/(1 + s²) ≥ 1/(1 + max(lo², hi²))` between the edges.
    #[inline]
    pub(crate) fn locate_with_clearance(&self, t: f64) -> Option<(usize, f64)> {
        let k = usize::try_from(self.locate(t)?).ok()?;
        let [lo, hi] = *self.clear.get(k)?;
        let gap = (t - lo).min(hi - t);
        Some((k, gap / (1.0 + (lo * lo).max(hi * hi))))
    }
}

/// Denominators of the addition formula below this are not divided by: the
/// angle sum nears ±π/2, where its tangent loses its precision and its sign.
const MIN_DENOMINATOR: f64 = 0.1;

/// `tan(θ + φ)` from `tan θ = t` and `tan φ = u` (θ, φ within ±π/2), or
/// `±∞` when the sum is beyond ±87° (the axes with a table end before 86°):
/// a denominator `1 − tu` under 0.1 means `tu > 0.9`, so θ and φ have one sign
/// and `|θ + φ| ≥ 2 atan √0.9 ≈ 87°`. NaN stays NaN.
#[inline]
pub(crate) fn tan_sum(t: f64, u: f64) -> f64 {
    let denominator = 1.0 - t * u;
    if denominator >= MIN_DENOMINATOR {
        (t + u) / denominator
    } else if t + u > 0.0 {
        f64::INFINITY
    } else if t + u < 0.0 {
        f64::NEG_INFINITY
    } else {
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axis(count: usize, step_deg: f64) -> Axis {
        let step = step_deg.to_radians();
        Axis {
            start: -(count as f64) * step / 2.0,
            step,
            count,
        }
    }

    #[test]
    fn a_decided_tangent_is_the_angle_s_bin() {
        let axis = axis(361, 0.25);
        let bins = TangentBins::new(&axis);
        let mut decided = 0;
        for i in 0..200_000 {
            let angle = -1.2 + 2.4 * i as f64 / 200_000.0;
            let exact = axis.index(angle);
            if let Some(k) = bins.locate(angle.tan()) {
                decided += 1;
                if (0..axis.count as isize).contains(&exact) {
                    assert_eq!(k, exact, "{angle}");
                } else {
                    assert_eq!(k < 0, exact < 0, "{angle}");
                    assert_eq!(k >= axis.count as isize, exact >= axis.count as isize);
                }
            }
        }
        assert!(decided > 199_900, "{decided}");
    }

    #[test]
    fn a_clearance_never_exceeds_the_angles_distance_to_the_edges() {
        let axis = axis(361, 0.25);
        let bins = TangentBins::new(&axis);
        let (mut decided, mut close) = (0, 0);
        for i in 0..200_000 {
            // The axis spans ±45°.
            let angle = -0.8 + 1.6 * i as f64 / 200_000.0;
            let Some((k, clearance)) = bins.locate_with_clearance(angle.tan()) else {
                continue;
            };
            decided += 1;
            assert_eq!(k as isize, axis.index(angle), "{angle}");
            let lower = axis.start + k as f64 * axis.step;
            let exact = (angle - lower).min(lower + axis.step - angle);
            assert!(clearance <= exact, "{angle}: {clearance} > {exact}");
            close += usize::from(clearance > 0.98 * exact - 1e-9);
        }
        // Not needlessly small: within a fiftieth of the truth (the slope of
        // `atan` varies that much across a 0.25° bin at 45°).
        assert!(
            decided > 196_000 && close == decided,
            "{close} of {decided}"
        );
        assert_eq!(bins.locate_with_clearance(2.0), None); // off the axis
    }

    #[test]
    fn an_axis_near_the_pole_has_no_table() {
        let wide = axis(800, 0.25); // ±100°
        assert_eq!(TangentBins::new(&wide).locate(0.0), None);
        // 50° + 40°: beyond every table; 30° + 20° by the formula.
        let (t, u) = (50f64.to_radians().tan(), 40f64.to_radians().tan());
        assert_eq!(tan_sum(t, u), f64::INFINITY);
        assert_eq!(tan_sum(-t, -u), f64::NEG_INFINITY);
        assert!(tan_sum(f64::NAN, u).is_nan());
        let sum = tan_sum(0.3f64.tan(), 0.2f64.tan());
        assert!((sum - 0.5f64.tan()).abs() < 1e-15);
        // The smallest sum the infinite branch stands for: tu = 0.9 at θ = φ.
        let half = 0.9f64.sqrt().atan();
        assert!(2.0 * half > MAX_ANGLE + 0.01);
    }
}
