//! Staged output: a result appears whole or not at all, and sigmap never
//! deletes a file or folder it did not write.
//!
//! A file is written to a hidden sibling (`.NAME.partial-PID@HOST`), synced
//! and renamed over its target. A folder is filled as a hidden sibling and
//! renamed into place; every folder sigmap writes carries a [`MARKER`] file,
//! and an existing target folder is replaced only if it is empty or carries
//! that marker (the old folder is moved aside first, so a kill between the
//! two renames loses nothing).

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The file that marks a folder as sigmap's output.
pub const MARKER: &str = ".sigmap-output";

/// `dir/.NAME.TAG-PID@HOST`: a hidden sibling of `path`, named for this
/// process and host (a results folder on a shared filesystem is seen by
/// processes of several hosts).
fn sibling(path: &Path, tag: &str) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    parent(path).join(format!(".{name}.{tag}-{}", Owner::me()))
}

/// Whether process `pid` of this host is known to have ended (never our
/// own).
pub fn process_gone(pid: u32) -> bool {
    pid != std::process::id() && !alive(pid)
}

/// A process on a host: who wrote a lock or a staging leftover.
#[derive(Clone, Debug, PartialEq)]
struct Owner {
    pid: u32,
    /// `None`: written by an older sigmap that did not record it (taken as
    /// this host).
    host: Option<String>,
}

impl Owner {
    fn me() -> Owner {
        Owner {
            pid: std::process::id(),
            host: Some(this_host()),
        }
    }

    /// `PID@HOST` or `PID`.
    fn parse(text: &str) -> Option<Owner> {
        let (pid, host) = match text.trim().split_once('@') {
            Some((pid, host)) if !host.is_empty() => (pid, Some(host.to_string())),
            Some(_) => return None,
            None => (text.trim(), None),
        };
        Some(Owner {
            pid: pid.parse().ok()?,
            host,
        })
    }

    /// Whether it is this host's (so whether it runs can be told here).
    fn is_local(&self) -> bool {
        self.host.as_deref().is_none_or(|h| h == this_host())
    }

    /// Known to have ended: a process of this host that no longer runs.
    fn is_gone(&self) -> bool {
        self.is_local() && self.pid != std::process::id() && !alive(self.pid)
    }
}

impl std::fmt::Display for Owner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}@{}", self.pid, self.host.as_deref().unwrap_or("?"))
    }
}

/// This machine's host name ('@' and '/' replaced, so that it fits a file
/// name and parses back).
fn this_host() -> String {
    let host = gethostname::gethostname().to_string_lossy().into_owned();
    let host: String = host
        .chars()
        .map(|c| {
            if c == '@' || c == '/' || c.is_whitespace() {
                '_'
            } else {
                c
            }
        })
        .collect();
    if host.is_empty() {
        "localhost".into()
    } else {
        host
    }
}

/// The folder holding `path` (`.` for a bare name).
fn parent(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// True while process `pid` runs (on Linux, `/proc/PID` exists; elsewhere
/// every process is assumed alive, so nothing is removed).
fn alive(pid: u32) -> bool {
    if cfg!(target_os = "linux") {
        Path::new(&format!("/proc/{pid}")).exists()
    } else {
        true
    }
}

/// Removes the staging leftovers of `path` (`.NAME.partial-PID@HOST`,
/// `.NAME.old-PID@HOST`) whose process is gone: a run of this host killed
/// mid-write. Another host's are left alone (whether that process runs
/// cannot be told from here). An old folder whose replacement never arrived
/// is moved back.
pub fn clean_stale(path: &Path) {
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return;
    };
    let Ok(entries) = std::fs::read_dir(parent(path)) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        for tag in ["partial", "old"] {
            let Some(owner) = file
                .strip_prefix(&format!(".{name}.{tag}-"))
                .and_then(Owner::parse)
            else {
                continue;
            };
            if !owner.is_gone() {
                continue;
            }
            let stale = entry.path();
            if tag == "old" && !path.exists() {
                let _ = std::fs::rename(&stale, path);
            } else if stale.is_dir() {
                let _ = std::fs::remove_dir_all(&stale);
            } else {
                let _ = std::fs::remove_file(&stale);
            }
        }
    }
}

/// Writes `bytes` to `path` through a synced staging file and a rename: a
/// full disk or a kill leaves the previous file (or none), never half a file.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = parent(path);
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    clean_stale(path);
    let staging = sibling(path, "partial");
    let written = (|| {
        let mut file = std::fs::File::create(&staging)?;
        file.write_all(bytes)?;
        file.sync_all()
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&staging);
        return Err(Error::io(path, e));
    }
    std::fs::rename(&staging, path).map_err(|e| {
        let _ = std::fs::remove_file(&staging);
        Error::io(path, e)
    })
}

/// True when `dir` is a folder sigmap may replace: empty, or marked as ours.
fn replaceable(dir: &Path) -> std::io::Result<bool> {
    if dir.join(MARKER).is_file() {
        return Ok(true);
    }
    Ok(std::fs::read_dir(dir)?.next().is_none())
}

/// Fills a fresh hidden sibling folder with `fill`, marks it, then moves it
/// to `out`. An existing `out` must be empty or an earlier sigmap output;
/// anything else is refused (exit 2) before any work is done.
pub fn write_folder(out: &Path, fill: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    if out.exists() {
        let ours = out.is_dir() && replaceable(out).map_err(|e| Error::io(out, e))?;
        if !ours {
            return Err(Error::input(
                out,
                format!(
                    "exists and was not written by sigmap (no {MARKER} inside); \
                     choose another --out or move it away"
                ),
            ));
        }
    }
    let dir = parent(out);
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    clean_stale(out);
    let staging = sibling(out, "partial");
    if staging.exists() {
        // Our own process id: a leftover of this very process.
        std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
    }
    std::fs::create_dir_all(&staging).map_err(|e| Error::io(out, e))?;
    let filled = fill(&staging).and_then(|()| {
        let marker = staging.join(MARKER);
        std::fs::write(
            &marker,
            "written by sigmap; sigmap replaces this folder when asked to write here again\n",
        )
        .map_err(|e| Error::io(&marker, e))
    });
    if let Err(e) = filled {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(e);
    }
    let old = sibling(out, "old");
    let moved_aside = out.exists();
    if moved_aside {
        std::fs::rename(out, &old).map_err(|e| Error::io(out, e))?;
    }
    if let Err(e) = std::fs::rename(&staging, out) {
        if moved_aside {
            let _ = std::fs::rename(&old, out);
        }
        return Err(Error::io(out, e));
    }
    if moved_aside {
        std::fs::remove_dir_all(&old).map_err(|e| Error::io(&old, e))?;
    }
    Ok(())
}

/// The files whose presence marks a results folder of `run`, `merge` or
/// `submit` as sigmap's: a run's or merge's manifest, a run's journal and
/// lock, a submission's record, the [`MARKER`] of a staged folder.
const RESULTS_MARKS: [&str; 5] = [
    "run.toml",
    "runs.journal.csv",
    RUN_LOCK,
    "submit.toml",
    MARKER,
];

/// A results folder's lock file ([`RunLock`]).
const RUN_LOCK: &str = ".sigmap-run.lock";

/// Creates the results folder `out`, or checks that the existing one may
/// take sigmap's files: empty (but for hidden files), or holding one of
/// [`RESULTS_MARKS`]. A
/// results folder gathers runs over several invocations, so its files are
/// written one by one rather than the folder replaced whole; this check is
/// what keeps them from replacing a user's own `runs.csv` or `report.html`.
pub fn claim_results_folder(out: &Path) -> Result<()> {
    if out.exists() {
        if !out.is_dir() {
            return Err(Error::input(
                out,
                "is a file, not a results folder: choose another --out",
            ));
        }
        let entries = std::fs::read_dir(out).map_err(|e| Error::io(out, e))?;
        let ours = RESULTS_MARKS.iter().any(|m| out.join(m).exists());
        // Hidden files (a `.gitignore`, a `.gitkeep`) are no obstacle: no
        // file sigmap writes there is hidden but its own marks and staging.
        let visible = entries
            .flatten()
            .any(|e| !e.file_name().to_string_lossy().starts_with('.'));
        if !ours && visible {
            return Err(Error::input(
                out,
                "holds files sigmap did not write (no run.toml, submit.toml or \
                 runs.journal.csv inside); choose another --out or move them away",
            ));
        }
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))
}

/// One writer per results folder: `.sigmap-run.lock` holds `PID@HOST` of
/// the `sigmap run` writing there, and goes when it ends.
pub struct RunLock {
    path: PathBuf,
}

impl RunLock {
    /// Takes the folder's lock, or says who holds it. A lock left by a
    /// process of this host that is gone is taken over; one of another host
    /// (a shared filesystem) is refused unless `break_lock`, since whether
    /// that process still runs cannot be told from here.
    pub fn acquire(dir: &Path, break_lock: bool) -> Result<RunLock> {
        let path = dir.join(RUN_LOCK);
        for _ in 0..2 {
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut file) => {
                    let _ = writeln!(file, "{}", Owner::me());
                    return Ok(RunLock { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let text = std::fs::read_to_string(&path).unwrap_or_default();
                    match Owner::parse(&text) {
                        Some(holder) if holder.is_local() && !holder.is_gone() => {
                            return Err(Error::input(
                                dir,
                                format!(
                                    "another sigmap run (process {}) is writing into this \
                                     folder; wait for it to end or choose another --out",
                                    holder.pid
                                ),
                            ))
                        }
                        Some(holder) if !holder.is_local() && !break_lock => {
                            return Err(Error::input(
                                dir,
                                format!(
                                    "process {} on host {} holds this folder's lock \
                                     (.sigmap-run.lock); from here sigmap cannot tell whether \
                                     it still runs: wait for it, or if it has ended rerun \
                                     with --break-lock",
                                    holder.pid,
                                    holder.host.as_deref().unwrap_or("?")
                                ),
                            ))
                        }
                        _ => {
                            let _ = std::fs::remove_file(&path);
                        }
                    }
                }
                Err(e) => return Err(Error::io(&path, e)),
            }
        }
        Err(Error::input(
            dir,
            "cannot take the folder's lock (.sigmap-run.lock)",
        ))
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// A file's stem as a name (`experiments/quickstart.toml`: `quickstart`).
pub fn stem(path: &Path) -> String {
    path.file_stem()
        .map_or_else(|| "unnamed".into(), |s| s.to_string_lossy().into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn put(dir: &Path, name: &str, text: &str) -> Result<()> {
        std::fs::write(dir.join(name), text).map_err(|e| Error::io(dir, e))
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("sigmap-files-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_folder_sigmap_did_not_write_is_never_replaced() {
        let root = scratch("foreign");
        let out = root.join("results");
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(out.join("thesis.tex"), "mine").unwrap();
        let err = write_folder(&out, |d| put(d, "a.csv", "x")).unwrap_err();
        assert_eq!(err.exit_code(), 2);
        assert!(err.to_string().contains("not written by sigmap"), "{err}");
        assert_eq!(
            std::fs::read_to_string(out.join("thesis.tex")).unwrap(),
            "mine"
        );
        assert!(!out.join("a.csv").exists());
        // Nothing left behind beside it.
        assert_eq!(std::fs::read_dir(&root).unwrap().count(), 1);
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_results_folder_of_the_users_own_files_is_refused() {
        let root = scratch("claim");
        // Created when missing; an empty one and sigmap's own are taken.
        let fresh = root.join("a/b");
        claim_results_folder(&fresh).unwrap();
        assert!(fresh.is_dir());
        claim_results_folder(&fresh).unwrap();
        std::fs::write(fresh.join(".gitignore"), "*\n").unwrap();
        claim_results_folder(&fresh).unwrap();
        for mark in RESULTS_MARKS {
            let out = root.join(format!("with{mark}"));
            std::fs::create_dir_all(&out).unwrap();
            std::fs::write(out.join(mark), "").unwrap();
            std::fs::write(out.join("runs.csv"), "sigmap's").unwrap();
            claim_results_folder(&out).unwrap();
        }
        // A folder of the user's files, and a file, are refused, untouched.
        let mine = root.join("mine");
        std::fs::create_dir_all(&mine).unwrap();
        std::fs::write(mine.join("runs.csv"), "mine").unwrap();
        let err = claim_results_folder(&mine).unwrap_err();
        assert_eq!(err.exit_code(), 2);
        assert!(err.to_string().contains("did not write"), "{err}");
        assert_eq!(std::fs::read_dir(&mine).unwrap().count(), 1);
        let file = mine.join("runs.csv");
        let err = claim_results_folder(&file).unwrap_err();
        assert!(err.to_string().contains("is a file"), "{err}");
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "mine");
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_sigmap_folder_is_replaced_whole_and_a_failure_keeps_the_old_one() {
        let root = scratch("ours");
        let out = root.join("scans");
        write_folder(&out, |d| put(d, "a.csv", "1")).unwrap();
        assert!(out.join(MARKER).is_file());
        write_folder(&out, |d| put(d, "b.csv", "2")).unwrap();
        assert!(
            !out.join("a.csv").exists(),
            "the old output is replaced, not merged"
        );
        assert_eq!(std::fs::read_to_string(out.join("b.csv")).unwrap(), "2");
        let failed = write_folder(&out, |d| {
            std::fs::write(d.join("c.csv"), "3").unwrap();
            Err(Error::Usage("disk full".into()))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read_to_string(out.join("b.csv")).unwrap(), "2");
        assert!(!out.join("c.csv").exists());
        // Only the output itself remains: no staging or old folders.
        assert_eq!(std::fs::read_dir(&root).unwrap().count(), 1);
        // An empty folder (made by the user for us) is fine.
        let empty = root.join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        write_folder(&empty, |d| put(d, "a.csv", "1")).unwrap();
        assert!(empty.join("a.csv").is_file());
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn leftovers_of_dead_processes_are_cleaned_and_a_live_lock_refuses() {
        let root = scratch("stale");
        let out = root.join("scans");
        // A process id that cannot be running (above Linux's pid_max), here
        // (old names without a host, and with this host's) and on another
        // host, whose leftovers are left alone: from here its process may
        // well be running.
        let dead = 4_999_999;
        let host = this_host();
        std::fs::create_dir_all(root.join(format!(".scans.partial-{dead}"))).unwrap();
        std::fs::write(root.join(format!(".map.bt.partial-{dead}@{host}")), "half").unwrap();
        let elsewhere = format!(".map.bt.partial-{dead}@node-17.cluster");
        std::fs::write(root.join(&elsewhere), "half").unwrap();
        write_folder(&out, |d| put(d, "a.csv", "1")).unwrap();
        write_file(&root.join("map.bt"), b"whole").unwrap();
        let mut names: Vec<String> = std::fs::read_dir(&root)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, [elsewhere.as_str(), "map.bt", "scans"]);
        // The lock: ours holds, a second is refused, a dead holder's is taken over.
        let lock_file = root.join(".sigmap-run.lock");
        let lock = RunLock::acquire(&root, false).unwrap();
        let text = std::fs::read_to_string(&lock_file).unwrap();
        assert_eq!(text, format!("{}@{host}\n", std::process::id()));
        std::fs::write(&lock_file, format!("1@{host}\n")).unwrap(); // pid 1 is alive
        let err = RunLock::acquire(&root, true).err().unwrap();
        assert!(err.to_string().contains("process 1"), "{err}");
        drop(lock);
        for dead_here in [format!("{dead}\n"), format!("{dead}@{host}\n")] {
            std::fs::write(&lock_file, dead_here).unwrap();
            drop(RunLock::acquire(&root, false).unwrap());
            assert!(!lock_file.exists());
        }
        // Another host's lock: refused, naming it, until --break-lock.
        std::fs::write(&lock_file, format!("{dead}@node-17.cluster\n")).unwrap();
        let err = RunLock::acquire(&root, false).err().unwrap().to_string();
        assert!(
            err.contains("node-17.cluster") && err.contains("--break-lock"),
            "{err}"
        );
        assert!(lock_file.exists());
        let lock = RunLock::acquire(&root, true).unwrap();
        let text = std::fs::read_to_string(&lock_file).unwrap();
        assert!(text.ends_with(&format!("@{host}\n")), "{text}");
        drop(lock);
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_file_is_replaced_whole_through_a_distinct_staging_name() {
        let root = scratch("file");
        let path = root.join("map.bt");
        std::fs::write(&path, "old").unwrap();
        write_file(&path, b"new").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_ne!(sibling(&path, "partial"), path);
        assert_eq!(std::fs::read_dir(&root).unwrap().count(), 1);
        // A target in a missing folder: the folder is made; a target that is
        // a folder fails and leaves it alone.
        write_file(&root.join("sub/map.ot"), b"x").unwrap();
        assert!(write_file(&root.join("sub"), b"x").is_err());
        assert!(root.join("sub/map.ot").is_file());
        std::fs::remove_dir_all(&root).unwrap();
    }
}
