//! Staged output: a result appears whole or not at all, and sigmap never
//! deletes a file or folder it did not write.
//!
//! A file is written to a hidden sibling (`.NAME.partial-PID`), synced and
//! renamed over its target. A folder is filled as a hidden sibling and
//! renamed into place; every folder sigmap writes carries a [`MARKER`] file,
//! and an existing target folder is replaced only if it is empty or carries
//! that marker (the old folder is moved aside first, so a kill between the
//! two renames loses nothing).

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The file that marks a folder as sigmap's output.
pub const MARKER: &str = ".sigmap-output";

/// `dir/.NAME.TAG-PID`: a hidden sibling of `path`.
fn sibling(path: &Path, tag: &str) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    parent(path).join(format!(".{name}.{tag}-{}", std::process::id()))
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

/// Removes the staging leftovers of `path` (`.NAME.partial-PID`,
/// `.NAME.old-PID`) whose process is gone: a run killed mid-write. An old
/// folder whose replacement never arrived is moved back.
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
            let Some(pid) = file
                .strip_prefix(&format!(".{name}.{tag}-"))
                .and_then(|p| p.parse::<u32>().ok())
            else {
                continue;
            };
            if pid == std::process::id() || alive(pid) {
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
    std::fs::create_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
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

/// One writer per results folder: `.sigmap-run.lock` holds the process id
/// of the `sigmap run` writing there, and goes when it ends.
pub struct RunLock {
    path: PathBuf,
}

impl RunLock {
    /// Takes the folder's lock, or says which process holds it. A lock left
    /// by a process that is gone is taken over.
    pub fn acquire(dir: &Path) -> Result<RunLock> {
        let path = dir.join(".sigmap-run.lock");
        for _ in 0..2 {
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut file) => {
                    let _ = writeln!(file, "{}", std::process::id());
                    return Ok(RunLock { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let holder = std::fs::read_to_string(&path)
                        .ok()
                        .and_then(|t| t.trim().parse::<u32>().ok());
                    match holder {
                        Some(pid) if alive(pid) => {
                            return Err(Error::input(
                                dir,
                                format!(
                                    "another sigmap run (process {pid}) is writing into this \
                                     folder; wait for it to end or choose another --out"
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
        // A process id that cannot be running (above Linux's pid_max).
        let dead = 4_999_999;
        std::fs::create_dir_all(root.join(format!(".scans.partial-{dead}"))).unwrap();
        std::fs::write(root.join(format!(".map.bt.partial-{dead}")), "half").unwrap();
        write_folder(&out, |d| put(d, "a.csv", "1")).unwrap();
        write_file(&root.join("map.bt"), b"whole").unwrap();
        let mut names: Vec<String> = std::fs::read_dir(&root)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["map.bt", "scans"]);
        // The lock: ours holds, a second is refused, a dead holder's is taken over.
        let lock = RunLock::acquire(&root).unwrap();
        std::fs::write(root.join(".sigmap-run.lock"), "1\n").unwrap(); // pid 1 is alive
        let err = RunLock::acquire(&root).err().unwrap();
        assert!(err.to_string().contains("process 1"), "{err}");
        drop(lock);
        std::fs::write(root.join(".sigmap-run.lock"), format!("{dead}\n")).unwrap();
        let lock = RunLock::acquire(&root).unwrap();
        drop(lock);
        assert!(!root.join(".sigmap-run.lock").exists());
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
