//! The one table of metrics: each metric's name (its `runs.csv` column), what
//! it means, how a run computes it from what the scorer and the consistency
//! check measured, whether `summary.csv` summarises it, and how far
//! `sigmap regress` lets its mean drift. Adding a metric is one entry of
//! [`METRICS`] (docs/architecture.md, "Adding a metric").

use crate::eval::scores::MapScores;
use crate::mapping::TreeStats;
use crate::uncertainty::consistency::ConsistencyReport;
use serde::de::{self, MapAccess, SeqAccess, Visitor};
use serde::ser::SerializeStruct;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

/// What one run measured of one method's map: the inputs of every metric.
pub struct Measured<'a> {
    /// Map against truth over the observable cells.
    pub scores: &'a MapScores,
    /// Propagated points against the true surface points (`None` for a
    /// method that propagates nothing).
    pub consistency: Option<&'a ConsistencyReport>,
    /// NEES of the run's first hit (NaN without one).
    pub nees_point: f64,
    /// The map's size.
    pub stats: &'a TreeStats,
}

/// How a metric's values are written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A whole number (written without a decimal point).
    Count,
    /// A real number.
    Real,
}

/// How far `sigmap regress` lets a summarised metric's mean drift.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tolerance {
    /// Not in `summary.csv`.
    NotSummarised,
    /// Summarised; an absolute drift.
    Absolute(f64),
    /// Summarised; a fraction of the baseline's mean.
    Relative(f64),
}

/// Which way a metric improves: what `paired.csv`'s verdicts rank by.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Better {
    /// Lower is better (false-free rate, Brier, log-loss, unknown).
    Lower,
    /// Higher is better (precision, recall, F1, IoU, ROC AUC).
    Higher,
    /// Nearer this value is better (ANEES and NEES: 3, the dimension;
    /// coverage: the χ²₃ share).
    Toward(f64),
    /// Not ranked (counts, sizes, bands): never summarised.
    Unranked,
}

/// The interval a metric's values lie in: summary intervals are kept inside
/// it (docs/math.md §7.4).
pub type Range = (f64, f64);

/// A share of cells or points: [0, 1].
const RATE: Range = (0.0, 1.0);
/// Non-negative and unbounded: log-loss, ANEES, NEES.
const POSITIVE: Range = (0.0, f64::INFINITY);
/// Counts and sizes.
const COUNT: Range = (0.0, f64::INFINITY);

/// The share of 3-D Gaussian errors inside the 1, 2 and 3σ ellipsoids,
/// `P(χ²₃ ≤ k²)` (`consistency::expected_coverage`, checked in the tests).
pub const COVERAGE_3D: [f64; 3] = [
    0.198_748_043_098_799,
    0.738_535_870_050_889,
    0.970_709_113_465_112,
];

/// One metric.
pub struct Metric {
    /// The `runs.csv` column and the `summary.csv` metric name.
    pub name: &'static str,
    /// What it is.
    pub doc: &'static str,
    /// Count or real.
    pub kind: Kind,
    /// Summarised, and the regression tolerance.
    pub tolerance: Tolerance,
    /// Which way it improves.
    pub better: Better,
    /// Where its values lie.
    pub range: Range,
    /// Its value for one run of one method (NaN when it does not apply).
    pub value: fn(&Measured) -> f64,
}

impl Metric {
    /// Whether `summary.csv` carries its mean and interval.
    pub fn summarised(&self) -> bool {
        self.tolerance != Tolerance::NotSummarised
    }
}

fn consistency(m: &Measured, f: fn(&ConsistencyReport) -> f64) -> f64 {
    m.consistency.map_or(f64::NAN, f)
}

/// Scores in [0, 1] may drift by this much before `sigmap regress` fails.
const SCORE: Tolerance = Tolerance::Absolute(0.01);

/// Every metric, in `runs.csv` column order (after cell, seed, method and
/// resolution); `summary.csv` lists the summarised ones in this order.
pub const METRICS: [Metric; 22] = [
    Metric {
        name: "observable_cells",
        doc: "observable cells scored",
        kind: Kind::Count,
        tolerance: Tolerance::NotSummarised,
        better: Better::Unranked,
        range: COUNT,
        value: |m| m.scores.observable_cells as f64,
    },
    Metric {
        name: "occupied_cells",
        doc: "truly occupied observable cells",
        kind: Kind::Count,
        tolerance: Tolerance::NotSummarised,
        better: Better::Unranked,
        range: COUNT,
        value: |m| m.scores.occupied_cells as f64,
    },
    Metric {
        name: "precision",
        doc: "occupied precision, TP / (TP + FP)",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Higher,
        range: RATE,
        value: |m| m.scores.precision,
    },
    Metric {
        name: "recall",
        doc: "occupied recall, TP / truly occupied",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Higher,
        range: RATE,
        value: |m| m.scores.recall,
    },
    Metric {
        name: "f1",
        doc: "occupied F1",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Higher,
        range: RATE,
        value: |m| m.scores.f1,
    },
    Metric {
        name: "iou",
        doc: "occupied IoU, TP / (TP + FP + FN)",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Higher,
        range: RATE,
        value: |m| m.scores.iou,
    },
    Metric {
        name: "false_free_rate",
        doc: "truly occupied cells called free / truly occupied: the collision risk",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Lower,
        range: RATE,
        value: |m| m.scores.false_free_rate,
    },
    Metric {
        name: "false_free_rate_margin",
        doc: "the same within one cell of a surface",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Lower,
        range: RATE,
        value: |m| m.scores.false_free_rate_margin,
    },
    Metric {
        name: "false_occupied_rate",
        doc: "truly free cells called occupied / truly free",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Lower,
        range: RATE,
        value: |m| m.scores.false_occupied_rate,
    },
    Metric {
        name: "unknown_fraction",
        doc: "unknown cells / observable",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Lower,
        range: RATE,
        value: |m| m.scores.unknown_fraction,
    },
    Metric {
        name: "brier",
        doc: "Brier score over known cells",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Lower,
        range: RATE,
        value: |m| m.scores.brier,
    },
    Metric {
        name: "log_loss",
        doc: "log-loss over known cells",
        kind: Kind::Real,
        tolerance: Tolerance::Relative(0.05),
        better: Better::Lower,
        range: POSITIVE,
        value: |m| m.scores.log_loss,
    },
    Metric {
        name: "roc_auc",
        doc: "ROC AUC of P over known cells",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Higher,
        range: RATE,
        value: |m| m.scores.roc_auc,
    },
    Metric {
        name: "anees",
        doc: "ANEES of the propagated points against the true surface points (NaN for ray_update)",
        kind: Kind::Real,
        tolerance: Tolerance::Relative(0.05),
        better: Better::Toward(3.0),
        range: POSITIVE,
        value: |m| consistency(m, |r| r.anees),
    },
    Metric {
        name: "anees_low",
        doc: "lower end of the two-sided 95% χ² band of ANEES for this many independent points \
              (the points of a viewpoint share its pose error: a reference only)",
        kind: Kind::Real,
        tolerance: Tolerance::NotSummarised,
        better: Better::Unranked,
        range: POSITIVE,
        value: |m| consistency(m, |r| r.bounds.0),
    },
    Metric {
        name: "anees_high",
        doc: "upper end of that band",
        kind: Kind::Real,
        tolerance: Tolerance::NotSummarised,
        better: Better::Unranked,
        range: POSITIVE,
        value: |m| consistency(m, |r| r.bounds.1),
    },
    Metric {
        name: "nees_point",
        doc: "NEES of the run's first hit: independent across seeds, so its mean over N seeds \
              has the χ²₃ₙ/N band (docs/math.md §6.6)",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Toward(3.0),
        range: POSITIVE,
        value: |m| m.nees_point,
    },
    Metric {
        name: "coverage_1sigma",
        doc: "share of true points inside the 1σ ellipsoid",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Toward(COVERAGE_3D[0]),
        range: RATE,
        value: |m| consistency(m, |r| r.coverage[0]),
    },
    Metric {
        name: "coverage_2sigma",
        doc: "the same for 2σ",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Toward(COVERAGE_3D[1]),
        range: RATE,
        value: |m| consistency(m, |r| r.coverage[1]),
    },
    Metric {
        name: "coverage_3sigma",
        doc: "the same for 3σ",
        kind: Kind::Real,
        tolerance: SCORE,
        better: Better::Toward(COVERAGE_3D[2]),
        range: RATE,
        value: |m| consistency(m, |r| r.coverage[2]),
    },
    Metric {
        name: "nodes",
        doc: "octree nodes",
        kind: Kind::Count,
        tolerance: Tolerance::NotSummarised,
        better: Better::Unranked,
        range: COUNT,
        value: |m| m.stats.nodes as f64,
    },
    Metric {
        name: "bytes",
        doc: "octree bytes",
        kind: Kind::Count,
        tolerance: Tolerance::NotSummarised,
        better: Better::Unranked,
        range: COUNT,
        value: |m| m.stats.bytes as f64,
    },
];

/// The metric named `name`.
pub fn metric(name: &str) -> Option<&'static Metric> {
    METRICS.iter().find(|m| m.name == name)
}

/// The metrics of `summary.csv`, in order.
pub fn summarised() -> impl Iterator<Item = &'static Metric> {
    METRICS.iter().filter(|m| m.summarised())
}

/// The columns of `runs.csv` before the metrics.
const KEY_COLUMNS: [&str; 4] = ["cell", "seed", "method", "resolution"];

/// Every column of `runs.csv`.
const COLUMNS: [&str; KEY_COLUMNS.len() + METRICS.len()] = {
    let mut out = [""; KEY_COLUMNS.len() + METRICS.len()];
    let mut i = 0;
    while i < out.len() {
        out[i] = if i < KEY_COLUMNS.len() {
            KEY_COLUMNS[i]
        } else {
            METRICS[i - KEY_COLUMNS.len()].name
        };
        i += 1;
    }
    out
};

/// The header line of `runs.csv` (no newline).
pub fn header() -> String {
    COLUMNS.join(",")
}

/// One row of `runs.csv`: a run (cell, seed), a method, and every metric of
/// [`METRICS`].
#[derive(Clone, Debug, PartialEq)]
pub struct RunRow {
    /// The sweep cell, `field=value;...` (empty without a sweep).
    pub cell: String,
    /// The run's seed.
    pub seed: u64,
    /// The modelling method.
    pub method: String,
    /// Map resolution (m).
    pub resolution: f64,
    /// The value of each metric of [`METRICS`], in its order.
    pub values: [f64; METRICS.len()],
}

impl RunRow {
    /// The row of a run, each metric computed from `measured`.
    pub fn new(
        cell: String,
        seed: u64,
        method: &str,
        resolution: f64,
        measured: &Measured,
    ) -> Self {
        Self {
            cell,
            seed,
            method: method.into(),
            resolution,
            values: METRICS.map(|m| (m.value)(measured)),
        }
    }

    /// The value of the metric `name` (NaN for an unknown name).
    pub fn get(&self, name: &str) -> f64 {
        METRICS
            .iter()
            .position(|m| m.name == name)
            .map_or(f64::NAN, |i| self.values[i])
    }

    /// Sets the value of the metric `name`; false for an unknown name.
    pub fn set(&mut self, name: &str, value: f64) -> bool {
        match METRICS.iter().position(|m| m.name == name) {
            Some(i) => {
                self.values[i] = value;
                true
            }
            None => false,
        }
    }
}

impl Serialize for RunRow {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut s = serializer.serialize_struct("RunRow", COLUMNS.len())?;
        s.serialize_field("cell", &self.cell)?;
        s.serialize_field("seed", &self.seed)?;
        s.serialize_field("method", &self.method)?;
        s.serialize_field("resolution", &self.resolution)?;
        for (m, v) in METRICS.iter().zip(&self.values) {
            match m.kind {
                Kind::Count if v.is_finite() && *v >= 0.0 => {
                    s.serialize_field(m.name, &(*v as u64))?;
                }
                _ => s.serialize_field(m.name, v)?,
            }
        }
        s.end()
    }
}

impl<'de> Deserialize<'de> for RunRow {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_struct("RunRow", &COLUMNS, RowVisitor)
    }
}

struct RowVisitor;

/// A row under construction: one slot per column.
#[derive(Default)]
struct Partial {
    cell: Option<String>,
    seed: Option<u64>,
    method: Option<String>,
    numbers: [Option<f64>; COLUMNS.len()],
}

impl Partial {
    fn finish<E: de::Error>(self) -> Result<RunRow, E> {
        let missing = |i: usize| E::missing_field(COLUMNS[i]);
        let mut values = [0.0; METRICS.len()];
        for (i, v) in values.iter_mut().enumerate() {
            *v = self.numbers[KEY_COLUMNS.len() + i]
                .ok_or_else(|| missing(KEY_COLUMNS.len() + i))?;
        }
        Ok(RunRow {
            cell: self.cell.ok_or_else(|| missing(0))?,
            seed: self.seed.ok_or_else(|| missing(1))?,
            method: self.method.ok_or_else(|| missing(2))?,
            resolution: self.numbers[3].ok_or_else(|| missing(3))?,
            values,
        })
    }
}

impl<'de> Visitor<'de> for RowVisitor {
    type Value = RunRow;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a runs.csv row of {} columns", COLUMNS.len())
    }

    /// A headerless row (the journal): the columns in order.
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<RunRow, A::Error> {
        let mut row = Partial::default();
        let short = |i: usize| de::Error::invalid_length(i, &self);
        row.cell = Some(seq.next_element()?.ok_or_else(|| short(0))?);
        row.seed = Some(seq.next_element()?.ok_or_else(|| short(1))?);
        row.method = Some(seq.next_element()?.ok_or_else(|| short(2))?);
        for i in KEY_COLUMNS.len() - 1..COLUMNS.len() {
            row.numbers[i] = Some(seq.next_element()?.ok_or_else(|| short(i))?);
        }
        row.finish()
    }

    /// A row under a header (runs.csv): the columns by name; unknown ones
    /// are ignored.
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<RunRow, A::Error> {
        let mut row = Partial::default();
        while let Some(key) = map.next_key::<String>()? {
            match COLUMNS.iter().position(|c| *c == key) {
                Some(0) => row.cell = Some(map.next_value()?),
                Some(1) => row.seed = Some(map.next_value()?),
                Some(2) => row.method = Some(map.next_value()?),
                Some(i) => row.numbers[i] = Some(map.next_value()?),
                None => {
                    map.next_value::<de::IgnoredAny>()?;
                }
            }
        }
        row.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_columns_follow_the_table() {
        for (i, m) in METRICS.iter().enumerate() {
            assert!(
                METRICS[..i].iter().all(|o| o.name != m.name),
                "{} twice",
                m.name
            );
            assert_eq!(COLUMNS[KEY_COLUMNS.len() + i], m.name);
        }
    }

    #[test]
    fn rows_round_trip_with_and_without_a_header() {
        let scores = MapScores {
            observable_cells: 1234,
            precision: 0.875,
            ..MapScores::default()
        };
        let stats = TreeStats {
            nodes: 9,
            leaves: 8,
            inner: 1,
            bytes: 4096,
        };
        let measured = Measured {
            scores: &scores,
            consistency: None,
            nees_point: f64::NAN,
            stats: &stats,
        };
        let row = RunRow::new("a=1".into(), 7, "unscented", 0.01, &measured);
        assert_eq!(row.get("precision"), 0.875);
        assert!(row.get("anees").is_nan());
        for headers in [true, false] {
            let mut bytes = Vec::new();
            {
                let mut w = csv::WriterBuilder::new()
                    .has_headers(headers)
                    .from_writer(&mut bytes);
                w.serialize(&row).unwrap();
                w.serialize(&row).unwrap();
            }
            let text = String::from_utf8(bytes.clone()).unwrap();
            if headers {
                assert!(text.starts_with(&COLUMNS.join(",")), "{text}");
            }
            assert!(
                text.contains(",1234,"),
                "counts without a decimal point: {text}"
            );
            let back: Vec<RunRow> = csv::ReaderBuilder::new()
                .has_headers(headers)
                .from_reader(bytes.as_slice())
                .deserialize()
                .collect::<Result<_, _>>()
                .unwrap();
            assert_eq!(back.len(), 2);
            // NaN != NaN: compare the bytes they write.
            assert_eq!(format!("{:?}", back[0]), format!("{row:?}"));
        }
        // A short row or a missing column is an error, not a default.
        let short = "a,7,unscented,0.01,1\n";
        let read: Result<Vec<RunRow>, _> = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(short.as_bytes())
            .deserialize()
            .collect();
        assert!(read.is_err());
        let missing = "cell,seed,method,resolution\na,7,unscented,0.01\n";
        let read: Result<Vec<RunRow>, _> = csv::Reader::from_reader(missing.as_bytes())
            .deserialize()
            .collect();
        assert!(read.unwrap_err().to_string().contains("observable_cells"));
    }
}
