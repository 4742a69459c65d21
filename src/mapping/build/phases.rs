//! Where a map's time goes: each step of each OPDF grid, or of each scan of
//! the ray update, timed and summed over the scans
//! ([`BuildExtras::phases`](super::BuildExtras)), for the benchmarks that say
//! what a map costs.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Instant;

/// The steps of a map whose time is summed: an OPDF map's four
/// ([`Phase::ALL`]), the ray update's two ([`Phase::RAY_UPDATE`]).
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
    /// The ray update's cells of a scan: its rays walked and the cells met
    /// listed (a discretized insertion's end cells first found).
    RayWalk,
    /// The ray update's cells of a scan applied to the tree: its upkeep.
    TreeUpdate,
}

impl Phase {
    /// An OPDF map's phases, in the order a grid goes through them.
    pub const ALL: [Phase; 4] = [Phase::Grid, Phase::Index, Phase::Search, Phase::Apply];

    /// The ray update's phases, in the order a scan goes through them.
    pub const RAY_UPDATE: [Phase; 2] = [Phase::RayWalk, Phase::TreeUpdate];

    /// Its name in a report.
    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Grid => "local grids",
            Phase::Index => "surface-cell index",
            Phase::Search => "merge search",
            Phase::Apply => "apply",
            Phase::RayWalk => "ray walk",
            Phase::TreeUpdate => "tree update",
        }
    }
}

/// The time spent in each [`Phase`], summed over scans and threads (on
/// several threads, thread time: more than the wall time).
#[derive(Debug, Default)]
pub struct PhaseTimes {
    nanos: [AtomicU64; Phase::ALL.len() + Phase::RAY_UPDATE.len()],
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
