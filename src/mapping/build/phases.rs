//! Where an OPDF map's time goes: each step of each grid timed and summed
//! over the scans ([`BuildExtras::phases`](super::BuildExtras)), for the
//! benchmarks that say what a map costs.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Instant;

/// The steps of an OPDF map whose time is summed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Each scan's local grid: propagation, bins, nearest surfaces, samples.
    Grid,
    /// The grid's surface-cell index.
    Index,
    /// The merge's search of the tree's cells.
    Search,
    /// The search's changes applied to the tree.
    Apply,
}

impl Phase {
    /// Every phase, in the order a grid goes through them.
    pub const ALL: [Phase; 4] = [Phase::Grid, Phase::Index, Phase::Search, Phase::Apply];

    /// Its name in a report.
    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Grid => "local grids",
            Phase::Index => "surface-cell index",
            Phase::Search => "merge search",
            Phase::Apply => "apply",
        }
    }
}

/// The time spent in each [`Phase`], summed over scans and threads (on
/// several threads, thread time: more than the wall time).
#[derive(Debug, Default)]
pub struct PhaseTimes {
    nanos: [AtomicU64; 4],
}

impl PhaseTimes {
    /// `work()`, its time added to `phase`.
    pub(super) fn time<T>(&self, phase: Phase, work: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = work();
        let nanos = u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
        self.nanos[phase as usize].fetch_add(nanos, Relaxed);
        out
    }

    /// The seconds summed in `phase` so far.
    pub fn seconds(&self, phase: Phase) -> f64 {
        self.nanos[phase as usize].load(Relaxed) as f64 * 1e-9
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_each_phase_apart() {
        let times = PhaseTimes::default();
        let pause = std::time::Duration::from_millis(20);
        assert_eq!(times.time(Phase::Index, || 7), 7);
        times.time(Phase::Search, || std::thread::sleep(pause));
        times.time(Phase::Search, || std::thread::sleep(pause));
        assert!(times.seconds(Phase::Search) >= 0.04);
        assert_eq!(times.seconds(Phase::Grid), 0.0);
        assert!(times.seconds(Phase::Index) < 0.04);
    }
}
