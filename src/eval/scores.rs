//! Scores of one map against the ground truth (docs/math.md §7.2–7.3), over the
//! cells some true beam could have seen.

use crate::mapping::octree::{Key, DEPTH};
use crate::mapping::opdf::probability;
use crate::mapping::Octree;
use rustc_hash::FxHashSet;
use serde::Serialize;

/// |log-odds| below this counts as unknown in the statistics (docs/math.md §4.6).
pub const UNKNOWN_BAND: f32 = 0.1;

/// Map-vs-truth scores over the observable cells.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct MapScores {
    /// Observable cells scored.
    pub observable_cells: usize,
    /// Truly occupied observable cells.
    pub occupied_cells: usize,
    /// TP / (TP + FP) for the occupied class.
    pub precision: f64,
    /// TP / (truly occupied).
    pub recall: f64,
    /// Harmonic mean of precision and recall.
    pub f1: f64,
    /// TP / (TP + FP + FN).
    pub iou: f64,
    /// Truly occupied cells the map calls free / truly occupied: the collision risk.
    pub false_free_rate: f64,
    /// The same over every cell within one cell (26-neighbourhood) of a truly occupied cell.
    pub false_free_rate_margin: f64,
    /// Truly free cells the map calls occupied / truly free.
    pub false_occupied_rate: f64,
    /// Cells the map does not know (never updated or |L| < 0.1) / observable.
    pub unknown_fraction: f64,
    /// Mean squared error of the occupancy probability over known cells.
    pub brier: f64,
    /// Mean negative log-likelihood over known cells (P clipped to [1e-6, 1 − 1e-6]).
    pub log_loss: f64,
    /// Area under the ROC curve of P over known cells.
    pub roc_auc: f64,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Call {
    Occupied,
    Free,
    Unknown,
}

fn call(log_odds: Option<f32>) -> Call {
    match log_odds {
        Some(l) if l >= UNKNOWN_BAND => Call::Occupied,
        Some(l) if l <= -UNKNOWN_BAND => Call::Free,
        _ => Call::Unknown,
    }
}

/// How a map calls a scored cell wrongly.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellError {
    /// Truly occupied, called free: the collision risk.
    FalseFree,
    /// Truly free, called occupied.
    FalseOccupied,
}

impl CellError {
    /// The name `sigmap score --errors` writes.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::FalseFree => "false_free",
            Self::FalseOccupied => "false_occupied",
        }
    }
}

/// A scored finest cell the map calls wrongly, with the map's log-odds there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WrongCell {
    /// The cell.
    pub key: Key,
    /// How it is wrong.
    pub error: CellError,
    /// The map's log-odds of the cell.
    pub log_odds: f32,
}

/// The scored cells (`observable` and known to the truth) that `map` calls
/// wrongly, in Morton order: the cells [`score_map`] counts in the false-free
/// and false-occupied rates.
pub fn wrong_cells(map: &Octree, truth: &Octree, observable: &FxHashSet<u64>) -> Vec<WrongCell> {
    let mut cells: Vec<u64> = observable.iter().copied().collect();
    cells.sort_unstable();
    cells
        .into_iter()
        .filter_map(|code| {
            let key = Key::from_morton(code);
            let truly = truth.query(&key, DEPTH)? >= 0.0;
            let log_odds = map.query(&key, DEPTH)?;
            let error = match (truly, call(Some(log_odds))) {
                (true, Call::Free) => CellError::FalseFree,
                (false, Call::Occupied) => CellError::FalseOccupied,
                _ => return None,
            };
            Some(WrongCell {
                key,
                error,
                log_odds,
            })
        })
        .collect()
}

/// Scores `map` against `truth` over the `observable` finest cells (Morton
/// codes). Both trees must have the same resolution.
pub fn score_map(map: &Octree, truth: &Octree, observable: &FxHashSet<u64>) -> MapScores {
    let mut cells: Vec<u64> = observable.iter().copied().collect();
    cells.sort_unstable();
    let mut c = Calls::count(map, truth, &cells);
    let (near, near_free) = free_near_surfaces(map, truth, &cells, &c.occupied_keys);
    let ratio = |a: usize, b: usize| {
        if b == 0 {
            f64::NAN
        } else {
            a as f64 / b as f64
        }
    };
    let precision = ratio(c.tp, c.tp + c.fp);
    let recall = ratio(c.tp, c.occupied);
    MapScores {
        observable_cells: c.scored,
        occupied_cells: c.occupied,
        precision,
        recall,
        f1: 2.0 * precision * recall / (precision + recall),
        iou: ratio(c.tp, c.tp + c.fp + c.fn_),
        false_free_rate: ratio(c.false_free, c.occupied),
        false_free_rate_margin: ratio(near_free, near),
        false_occupied_rate: ratio(c.false_occupied, c.free),
        unknown_fraction: ratio(c.unknown, c.scored),
        brier: brier(&c.known),
        log_loss: log_loss(&c.known),
        roc_auc: roc_auc(&mut c.known),
    }
}

/// What a map calls the scored cells, against the truth.
#[derive(Default)]
struct Calls {
    /// Observable cells the truth knows (the scored ones).
    scored: usize,
    /// Truly occupied, called occupied.
    tp: usize,
    /// Truly free, called occupied.
    fp: usize,
    /// Truly occupied, not called occupied.
    fn_: usize,
    /// Truly occupied, called free.
    false_free: usize,
    /// Truly free, called occupied.
    false_occupied: usize,
    /// Truly occupied cells.
    occupied: usize,
    /// Truly free cells.
    free: usize,
    /// Cells the map does not know.
    unknown: usize,
    /// The known cells' occupancy probability and truth.
    known: Vec<(f64, bool)>,
    /// The truly occupied cells (Morton codes).
    occupied_keys: FxHashSet<u64>,
}

impl Calls {
    /// Counts the calls of `map` over `cells` (sorted Morton codes).
    fn count(map: &Octree, truth: &Octree, cells: &[u64]) -> Self {
        let mut c = Calls::default();
        for code in cells {
            let key = Key::from_morton(*code);
            let Some(t) = truth.query(&key, DEPTH) else {
                continue;
            };
            c.scored += 1;
            let truly = t >= 0.0;
            let m = map.query(&key, DEPTH);
            let called = call(m);
            if truly {
                c.occupied += 1;
                c.occupied_keys.insert(*code);
            } else {
                c.free += 1;
            }
            match (truly, called) {
                (true, Call::Occupied) => c.tp += 1,
                (true, Call::Free) => {
                    c.false_free += 1;
                    c.fn_ += 1;
                }
                (true, Call::Unknown) => c.fn_ += 1,
                (false, Call::Occupied) => {
                    c.fp += 1;
                    c.false_occupied += 1;
                }
                _ => {}
            }
            if called == Call::Unknown {
                c.unknown += 1;
            } else if let Some(l) = m {
                c.known.push((probability(l as f64), truly));
            }
        }
        c
    }
}

/// The safety margin: of the scored cells within one cell of a truly
/// occupied one, how many there are and how many the map calls free.
fn free_near_surfaces(
    map: &Octree,
    truth: &Octree,
    cells: &[u64],
    occupied_keys: &FxHashSet<u64>,
) -> (usize, usize) {
    let (mut near, mut near_free) = (0usize, 0usize);
    for code in cells {
        let key = Key::from_morton(*code);
        let close = (-1i32..=1).any(|dx| {
            (-1i32..=1).any(|dy| {
                (-1i32..=1).any(|dz| {
                    let n = Key([
                        (key.0[0] as i32 + dx) as u16,
                        (key.0[1] as i32 + dy) as u16,
                        (key.0[2] as i32 + dz) as u16,
                    ]);
                    occupied_keys.contains(&n.morton())
                })
            })
        });
        if close && truth.query(&key, DEPTH).is_some() {
            near += 1;
            if call(map.query(&key, DEPTH)) == Call::Free {
                near_free += 1;
            }
        }
    }
    (near, near_free)
}

/// The mean squared error of the known cells' probabilities.
fn brier(known: &[(f64, bool)]) -> f64 {
    let n = known.len() as f64;
    known
        .iter()
        .map(|(p, o)| (p - if *o { 1.0 } else { 0.0 }).powi(2))
        .sum::<f64>()
        / n
}

/// The mean negative log-likelihood of the known cells' truth
/// (probabilities clamped to [1e-6, 1 − 1e-6]).
fn log_loss(known: &[(f64, bool)]) -> f64 {
    let n = known.len() as f64;
    -known
        .iter()
        .map(|(p, o)| {
            let p = p.clamp(1e-6, 1.0 - 1e-6);
            if *o {
                p.ln()
            } else {
                (1.0 - p).ln()
            }
        })
        .sum::<f64>()
        / n
}

/// Area under the ROC curve (ties share their rank: the Mann–Whitney U).
pub fn roc_auc(scored: &mut [(f64, bool)]) -> f64 {
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let positives = scored.iter().filter(|s| s.1).count();
    let negatives = scored.len() - positives;
    if positives == 0 || negatives == 0 {
        return f64::NAN;
    }
    let mut rank_sum = 0.0;
    let mut i = 0;
    while i < scored.len() {
        let mut j = i;
        while j < scored.len() && scored[j].0 == scored[i].0 {
            j += 1;
        }
        let mid_rank = (i + j + 1) as f64 / 2.0; // ranks i+1 ..= j
        rank_sum += mid_rank * scored[i..j].iter().filter(|s| s.1).count() as f64;
        i = j;
    }
    (rank_sum - positives as f64 * (positives as f64 + 1.0) / 2.0)
        / (positives as f64 * negatives as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::Clamp;

    #[test]
    fn the_wrong_cells_are_the_ones_the_rates_count() {
        // A row of ten cells, truly occupied from x = 6 on; the map calls
        // x = 2 occupied, x = 7 free, leaves x = 8 unknown and x = 9 absent.
        let (mut truth, mut map) = (Octree::new(0.1), Octree::new(0.1));
        let mut observable = FxHashSet::default();
        let key = |x: u16| Key([32768 + x, 32768, 32768]);
        for x in 0..10u16 {
            let occupied = x >= 6;
            let (lo, hi) = (Clamp::OCTOMAP.min, Clamp::OCTOMAP.max);
            truth.update(&key(x), if occupied { hi } else { lo }, Clamp::OCTOMAP);
            observable.insert(key(x).morton());
            let called = match x {
                2 => Some(1.0),
                7 => Some(-1.0),
                8 => Some(0.05),
                9 => None,
                _ if occupied => Some(1.0),
                _ => Some(-1.0),
            };
            if let Some(l) = called {
                map.update(&key(x), l, Clamp::OCTOMAP);
            }
        }
        let wrong = wrong_cells(&map, &truth, &observable);
        let listed: Vec<(u16, CellError)> = wrong
            .iter()
            .map(|w| (w.key.0[0] - 32768, w.error))
            .collect();
        assert_eq!(
            listed,
            [(2, CellError::FalseOccupied), (7, CellError::FalseFree)]
        );
        assert_eq!((wrong[0].log_odds, wrong[1].log_odds), (1.0, -1.0));
        let s = score_map(&map, &truth, &observable);
        assert_eq!(s.false_free_rate, 1.0 / 4.0);
        assert_eq!(s.false_occupied_rate, 1.0 / 6.0);
    }

    #[test]
    fn roc_auc_of_known_orders() {
        assert_eq!(
            roc_auc(&mut [(0.1, false), (0.9, true), (0.2, false), (0.8, true)]),
            1.0
        );
        assert_eq!(roc_auc(&mut [(0.9, false), (0.1, true)]), 0.0);
        assert_eq!(roc_auc(&mut [(0.5, false), (0.5, true)]), 0.5);
    }

    #[test]
    fn perfect_and_wrong_maps() {
        let mut truth = Octree::new(0.1);
        let mut observable = FxHashSet::default();
        for x in 0..10u16 {
            let key = Key([32768 + x, 32768, 32768]);
            let occupied = x == 9;
            truth.update(
                &key,
                if occupied {
                    Clamp::OCTOMAP.max
                } else {
                    Clamp::OCTOMAP.min
                },
                Clamp::OCTOMAP,
            );
            observable.insert(key.morton());
        }
        let perfect = score_map(&truth, &truth, &observable);
        assert_eq!(
            (
                perfect.precision,
                perfect.recall,
                perfect.false_free_rate,
                perfect.unknown_fraction
            ),
            (1.0, 1.0, 0.0, 0.0)
        );
        assert_eq!(perfect.roc_auc, 1.0);
        // Clamped log-odds cap confidence: P = 0.119 on free cells gives 0.014.
        assert!(perfect.brier < 0.015);
        // A map that carved the surface away: everything free.
        let mut carved = Octree::new(0.1);
        for x in 0..10u16 {
            carved.update(&Key([32768 + x, 32768, 32768]), -1.0, Clamp::OCTOMAP);
        }
        let s = score_map(&carved, &truth, &observable);
        assert_eq!(s.false_free_rate, 1.0);
        assert_eq!(s.recall, 0.0);
        assert!(s.false_free_rate_margin > 0.9);
        // An empty map knows nothing.
        let s = score_map(&Octree::new(0.1), &truth, &observable);
        assert_eq!(s.unknown_fraction, 1.0);
        assert_eq!(s.false_free_rate, 0.0);
    }
}
