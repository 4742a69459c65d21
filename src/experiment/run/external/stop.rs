//! Stopping a mapper's whole process group: at its timeout, once its
//! command has exited (whatever it left running), and when a signal stops
//! sigmap itself.
//!
//! A mapper runs in a process group of its own, so that a timeout stops
//! whatever its command started. The price: the terminal's Ctrl-C (SIGINT to
//! the foreground group), a closed terminal (SIGHUP) and a batch system's
//! SIGTERM to sigmap do not reach it. So every running mapper's group is
//! listed in [`RUNNING`], and while any has run, sigmap catches those three
//! signals: its handler kills the listed groups, then lets the signal end
//! sigmap as it would have (the default action, raised again). A signal the
//! process was started ignoring (a `nohup` run) stays ignored.

use std::sync::atomic::{AtomicI32, Ordering};

/// The most mappers listed at once: one runs per worker thread.
const SLOTS: usize = 1024;

/// The process groups of the running mappers (0: a free slot).
static RUNNING: [AtomicI32; SLOTS] = [const { AtomicI32::new(0) }; SLOTS];

/// The signals that stop sigmap and, through the handler, its mappers.
const STOPPING: [libc::c_int; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

/// A running mapper's process group, listed from [`Group::list`] until it is
/// dropped, which kills whatever of the group still runs.
pub(super) struct Group {
    id: libc::pid_t,
    slot: Option<usize>,
}

impl Group {
    /// Lists the group `id` (a child started with `process_group(0)`: its
    /// process id) so that a stopping signal kills it; the handler is
    /// installed with the first group.
    pub(super) fn list(id: u32) -> Group {
        static HANDLER: std::sync::Once = std::sync::Once::new();
        HANDLER.call_once(install_handler);
        let id = libc::pid_t::try_from(id).unwrap_or(0);
        let slot = (id > 0)
            .then(|| {
                RUNNING.iter().position(|slot| {
                    slot.compare_exchange(0, id, Ordering::AcqRel, Ordering::Relaxed)
                        .is_ok()
                })
            })
            .flatten();
        Group { id, slot }
    }

    /// Sends SIGKILL to every process of the group.
    pub(super) fn kill(&self) {
        kill_group(self.id);
    }
}

impl Drop for Group {
    fn drop(&mut self) {
        // The command has been waited for: what it left running goes too,
        // before the group's id is given back.
        self.kill();
        if let Some(slot) = self.slot {
            RUNNING[slot].store(0, Ordering::Release);
        }
    }
}

/// SIGKILL to process group `id` (nothing for an id that is not a group's).
fn kill_group(id: libc::pid_t) {
    if id > 0 {
        // SAFETY: kill(2) with a negative pid signals that process group;
        // it reads no memory of ours.
        unsafe {
            libc::kill(-id, libc::SIGKILL);
        }
    }
}

/// Catches [`STOPPING`] with [`stop_mappers`], except a signal the process
/// ignores.
fn install_handler() {
    for signal in STOPPING {
        // SAFETY: sigaction(2) with zeroed structures (a valid empty mask)
        // reads the current disposition, then sets an `extern "C"` handler
        // that only calls async-signal-safe functions.
        unsafe {
            let mut current: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(signal, std::ptr::null(), &raw mut current) != 0
                || current.sa_sigaction == libc::SIG_IGN
            {
                continue;
            }
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = stop_mappers as extern "C" fn(libc::c_int) as libc::sighandler_t;
            libc::sigemptyset(&raw mut action.sa_mask);
            libc::sigaction(signal, &raw const action, std::ptr::null_mut());
        }
    }
}

/// The handler: kills every listed group, then ends sigmap by `signal`'s
/// default action.
extern "C" fn stop_mappers(signal: libc::c_int) {
    for slot in &RUNNING {
        kill_group(slot.load(Ordering::Acquire));
    }
    // SAFETY: signal(2) and raise(3) are async-signal-safe; the default
    // action of these signals ends the process.
    unsafe {
        libc::signal(signal, libc::SIG_DFL);
        libc::raise(signal);
    }
}
