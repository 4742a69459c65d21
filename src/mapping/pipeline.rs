//! Scans inserted in order while later scans are prepared: every thread of
//! the current rayon pool prepares scans one after another (each scan's work
//! itself parallel inside), and whichever thread finishes the scan next in
//! order inserts it, and any after it that are ready, into the map. No
//! thread waits for another at scan boundaries: the map's order-dependent
//! step (the tree update) runs beside the preparation of later scans, not
//! between them. The map is the same as inserting the scans one by one.

use std::collections::BTreeMap;
use std::sync::Mutex;

/// The scans prepared but not yet inserted, and who inserts.
struct Queue<T> {
    /// The next scan a thread may take up.
    next_taken: usize,
    /// The next scan to insert.
    next_inserted: usize,
    /// Prepared scans waiting for an earlier one.
    ready: BTreeMap<usize, T>,
    /// Whether a thread is inserting (it inserts every ready scan in turn).
    inserting: bool,
}

/// `insert(prepare(i))` for `i` in `0..count`, `insert` in order of `i`;
/// `prepare` runs on every thread of the current rayon pool, at most
/// `window` scans beyond the last inserted (so at most `window` prepared
/// scans are held). One thread: the plain loop.
pub fn prepare_and_insert<T: Send>(
    count: usize,
    window: usize,
    prepare: impl Fn(usize) -> T + Sync,
    mut insert: impl FnMut(T) + Send,
) {
    let threads = rayon::current_num_threads();
    if threads == 1 || count <= 1 {
        (0..count).for_each(|i| insert(prepare(i)));
        return;
    }
    let queue = Mutex::new(Queue {
        next_taken: 0,
        next_inserted: 0,
        ready: BTreeMap::new(),
        inserting: false,
    });
    // Only the thread holding `inserting` locks this: never contended.
    let inserter = Mutex::new(insert);
    let lock = || {
        queue
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    };
    let work = || loop {
        // Take up the next scan, unless the window is full: then the scans
        // in hand are enough, and this thread helps with their parallel
        // parts instead (it never blocks, so it cannot hold up another).
        let i = {
            let mut q = lock();
            if q.next_taken >= count || q.next_taken >= q.next_inserted + window.max(1) {
                return;
            }
            q.next_taken += 1;
            q.next_taken - 1
        };
        let prepared = prepare(i);
        let mut q = lock();
        q.ready.insert(i, prepared);
        if q.inserting {
            continue;
        }
        q.inserting = true;
        // Insert every scan that is next in order, the lock released while
        // inserting.
        loop {
            let next = q.next_inserted;
            let Some(prepared) = q.ready.remove(&next) else {
                q.inserting = false;
                break;
            };
            drop(q);
            (inserter
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner))(prepared);
            q = lock();
            q.next_inserted += 1;
        }
    };
    rayon::scope(|s| {
        for _ in 1..threads {
            s.spawn(|_| work());
        }
        work();
    });
    debug_assert_eq!(lock().next_inserted, count, "every scan inserted");
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

    /// Busy work of `n` steps (a value the optimiser cannot drop).
    fn spin(n: u64) -> u64 {
        (0..n).fold(1u64, |a, k| {
            a.wrapping_mul(6364136223846793005).wrapping_add(k)
        })
    }

    #[test]
    fn scans_are_inserted_in_order_whatever_the_threads() {
        for threads in [1, 2, 3, 4] {
            for window in [1, 2, 5] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let held = AtomicUsize::new(0);
                let most_held = AtomicUsize::new(0);
                let mut order = Vec::new();
                pool.install(|| {
                    prepare_and_insert(
                        40,
                        window,
                        |i| {
                            // Uneven work, so that later scans finish first.
                            let n = held.fetch_add(1, Relaxed) + 1;
                            most_held.fetch_max(n, Relaxed);
                            (i, spin(((i * 7919) % 13) as u64 * 20_000))
                        },
                        |(i, _)| {
                            held.fetch_sub(1, Relaxed);
                            order.push(i);
                        },
                    );
                });
                assert_eq!(order, (0..40).collect::<Vec<_>>(), "{threads} threads");
                assert!(
                    most_held.load(Relaxed) <= window.max(1),
                    "{} prepared scans held with a window of {window}",
                    most_held.load(Relaxed)
                );
            }
        }
    }

    #[test]
    fn prepare_runs_on_several_threads_at_once() {
        // Scan 0's preparation waits until scan 1's has begun: only a second
        // thread can begin it. However slowly that thread starts, the test
        // passes once it does; the long guard only turns a broken pipeline
        // (one scan at a time) into a failure instead of a hang.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let (began, begun) = std::sync::mpsc::channel::<()>();
        let begun = std::sync::Mutex::new(begun);
        let overlapped = std::sync::atomic::AtomicBool::new(false);
        pool.install(|| {
            prepare_and_insert(
                4,
                4,
                |i| match i {
                    0 => {
                        let guard = std::time::Duration::from_secs(300);
                        let seen = begun.lock().unwrap().recv_timeout(guard).is_ok();
                        overlapped.store(seen, Relaxed);
                    }
                    1 => began.send(()).unwrap(),
                    _ => {}
                },
                |()| {},
            );
        });
        assert!(
            overlapped.load(Relaxed),
            "scan 1 was prepared only after scan 0"
        );
    }
}
