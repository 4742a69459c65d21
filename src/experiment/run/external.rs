//! External mappers (`[[mapper]]`): another program maps each run's exported
//! scans, and sigmap scores its map exactly like its own (docs/cli.md,
//! "Your own mapper in a sweep").
//!
//! The protocol: for every cell and seed sigmap exports the run's scans (the
//! believed poses only, as `sigmap export` writes them) into a private
//! folder, runs the command there without a shell, with a timeout, and reads
//! the octree file the command wrote. The command's arguments may hold the
//! placeholders of [`PLACEHOLDERS`].

use crate::error::{Error, Result};
use crate::experiment::output::export::{write_export, MapFrame};
use crate::geometry::Vector3;
use crate::mapping::depth_images::DepthCamera;
use crate::mapping::octomap_io::read_octree;
use crate::mapping::{Clamp, MapperView, Octree, Scan};
use serde::Deserialize;
use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The placeholders a mapper's `command` and `map` may hold, and what each
/// becomes.
pub const PLACEHOLDERS: [(&str, &str); 10] = [
    (
        "{scans}",
        "the run's OctoMap ScanGraph (believed poses only)",
    ),
    ("{poses}", "the viewpoints' poses, a TUM trajectory"),
    (
        "{plys}",
        "the folder of per-viewpoint PLYs (vp_NNN.ply, map frame)",
    ),
    (
        "{dir}",
        "a private empty folder for this run (the command's working folder)",
    ),
    ("{resolution}", "the experiment's resolution (m)"),
    ("{max_range}", "the scanner's maximum range (m)"),
    ("{seed}", "the run's seed"),
    (
        "{depth}",
        "a depth camera's images: the folder of depth.txt and depth/ (TUM RGB-D layout)",
    ),
    ("{intrinsics}", "a depth camera's fx,fy,cx,cy (px)"),
    ("{depth_scale}", "a depth camera's raw depth per metre"),
];

/// The placeholders of a depth camera's images, which a raster has not.
const DEPTH_PLACEHOLDERS: [&str; 3] = ["{depth}", "{intrinsics}", "{depth_scale}"];

/// The longest a mapper may be given (s): a day.
const MAX_TIMEOUT_S: f64 = 86_400.0;

/// How much of a failed mapper's stderr the error shows (bytes, its end).
const STDERR_TAIL: usize = 400;

/// A `[[mapper]]` table as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapperSpec {
    /// The method name its rows carry.
    pub name: String,
    /// The program and its arguments, with placeholders.
    pub command: Vec<String>,
    /// The octree file (`.bt` or `.ot`) the command writes, with
    /// placeholders; relative to `{dir}`.
    pub map: String,
    /// Seconds before the command is stopped (default 300).
    pub timeout_s: Option<f64>,
}

/// An external mapper, checked: a method of the experiment beside sigmap's own.
#[derive(Clone, Debug, PartialEq)]
pub struct ExternalMapper {
    /// The method name its rows carry.
    pub name: String,
    /// The program (as written) and its arguments; an argument naming a file
    /// beside the experiment is replaced by its absolute path.
    pub command: Vec<String>,
    /// The map file template.
    pub map: String,
    /// How long it may run.
    pub timeout: Duration,
    /// The experiment's folder, which relative paths start from.
    pub base: PathBuf,
}

impl MapperSpec {
    /// Checks the table: a new method name, a command, known placeholders
    /// (a depth camera's only with one: `camera`) and a sane timeout.
    /// `taken` are the names already in use. Errors are phrased for the
    /// experiment file.
    pub fn check(
        self,
        base: &Path,
        taken: &[&str],
        camera: bool,
    ) -> std::result::Result<ExternalMapper, String> {
        let name = self.name.trim().to_string();
        let what = format!("[[mapper]] '{name}'");
        let valid = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-';
        if name.is_empty() || !name.chars().all(valid) {
            return Err(format!(
                "{what}: a mapper's name is letters, digits, '_' and '-' (it names a method in \
                 runs.csv and a map file)"
            ));
        }
        if taken.contains(&name.as_str()) {
            return Err(format!(
                "{what}: the name is already a method of this experiment; give the mapper a \
                 name of its own"
            ));
        }
        if self.command.is_empty() || self.command[0].trim().is_empty() {
            return Err(format!("{what}: `command` must name a program"));
        }
        for text in self.command.iter().chain([&self.map]) {
            check_placeholders(text).map_err(|e| format!("{what}: {e}"))?;
            let depth = DEPTH_PLACEHOLDERS.iter().find(|p| text.contains(*p));
            if let (Some(placeholder), false) = (depth, camera) {
                return Err(format!(
                    "{what}: {placeholder} needs a depth camera's images, and the [sensor] is a \
                     raster scanner (model = \"pinhole\" gives a depth camera)"
                ));
            }
        }
        if self.map.trim().is_empty() {
            return Err(format!(
                "{what}: `map` must name the octree file the command writes"
            ));
        }
        let timeout_s = self.timeout_s.unwrap_or(300.0);
        if !timeout_s.is_finite() || timeout_s <= 0.0 || timeout_s > MAX_TIMEOUT_S {
            return Err(format!(
                "{what}: timeout_s = {timeout_s} must be positive seconds, at most \
                 {MAX_TIMEOUT_S} (a day)"
            ));
        }
        let command = self
            .command
            .iter()
            .enumerate()
            .map(|(i, arg)| match beside(base, arg) {
                Some(path) if i > 0 || arg.contains('/') => path.to_string_lossy().into_owned(),
                _ => arg.clone(),
            })
            .collect();
        Ok(ExternalMapper {
            name,
            command,
            map: self.map,
            timeout: Duration::from_secs_f64(timeout_s),
            base: base.to_path_buf(),
        })
    }
}

/// The file `arg` names beside the experiment (a relative path without
/// placeholders that exists there), absolute.
fn beside(base: &Path, arg: &str) -> Option<PathBuf> {
    if arg.contains('{') || arg.starts_with('-') || arg.is_empty() {
        return None;
    }
    let path = base.join(arg);
    path.is_file()
        .then(|| std::fs::canonicalize(&path).unwrap_or(path))
}

/// Refuses a `{...}` that is not one of [`PLACEHOLDERS`].
fn check_placeholders(text: &str) -> std::result::Result<(), String> {
    let mut rest = text;
    while let Some(start) = rest.find('{') {
        let end = rest[start..]
            .find('}')
            .ok_or_else(|| format!("'{text}' opens a placeholder it does not close"))?;
        let placeholder = &rest[start..start + end + 1];
        if !PLACEHOLDERS.iter().any(|(p, _)| *p == placeholder) {
            let known: Vec<&str> = PLACEHOLDERS.iter().map(|(p, _)| *p).collect();
            return Err(format!(
                "unknown placeholder {placeholder} in '{text}' (use {})",
                known.join(", ")
            ));
        }
        rest = &rest[start + end + 1..];
    }
    Ok(())
}

/// Where the run's inputs and the mapper's folder are, and the numbers the
/// placeholders stand for.
struct Placeholders {
    scans: PathBuf,
    poses: PathBuf,
    plys: PathBuf,
    dir: PathBuf,
    resolution: f64,
    max_range: f64,
    seed: u64,
    camera: Option<DepthCamera>,
}

impl Placeholders {
    fn fill(&self, text: &str) -> String {
        let path = |p: &Path| p.to_string_lossy().into_owned();
        let text = text
            .replace("{scans}", &path(&self.scans))
            .replace("{poses}", &path(&self.poses))
            .replace("{plys}", &path(&self.plys))
            .replace("{dir}", &path(&self.dir))
            .replace("{resolution}", &self.resolution.to_string())
            .replace("{max_range}", &self.max_range.to_string())
            .replace("{seed}", &self.seed.to_string());
        match &self.camera {
            // The export folder holds depth.txt and depth/.
            Some(c) => text
                .replace("{depth}", &path(&self.plys))
                .replace(
                    "{intrinsics}",
                    &format!("{:?},{:?},{:?},{:?}", c.fx, c.fy, c.cx, c.cy),
                )
                .replace("{depth_scale}", &c.scale.to_string()),
            None => text,
        }
    }
}

/// One run of a mapper: which cell and seed, with what scans.
pub struct MapperRun<'a> {
    /// The cell's label (for messages).
    pub cell: &'a str,
    /// The run's seed.
    pub seed: u64,
    /// What a mapper may know.
    pub view: &'a MapperView<'a>,
    /// The run's scans.
    pub scans: &'a [Scan],
    /// The map resolution (m).
    pub resolution: f64,
    /// `map = scene + offset`.
    pub offset: &'a Vector3,
    /// The clamp `.bt` leaves are read with.
    pub clamp: Clamp,
    /// A depth camera's intrinsics: its images are exported too.
    pub camera: Option<&'a DepthCamera>,
}

impl ExternalMapper {
    /// The command as a shell would show it (arguments with spaces or
    /// quotes single-quoted; placeholders unfilled). It runs without a
    /// shell.
    pub fn command_line(&self) -> String {
        let quoted = |arg: &String| {
            if arg.is_empty()
                || arg
                    .chars()
                    .any(|c| c.is_whitespace() || "'\"\\$`".contains(c))
            {
                format!("'{}'", arg.replace('\'', "'\\''"))
            } else {
                arg.clone()
            }
        };
        self.command
            .iter()
            .map(quoted)
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// The program the command runs: a path (relative to the experiment's
    /// folder) or a name looked up on `PATH`.
    pub fn program(&self) -> Result<PathBuf> {
        let program = &self.command[0];
        let found = if program.contains('/') {
            let path = self.base.join(program);
            path.is_file().then_some(path)
        } else {
            std::env::var_os("PATH").and_then(|paths| {
                std::env::split_paths(&paths)
                    .map(|dir| dir.join(program))
                    .find(|path| path.is_file())
            })
        };
        found.ok_or_else(|| {
            Error::Usage(format!(
                "mapper {}: the program '{program}' is not {} (install it, or give its path)",
                self.name,
                if program.contains('/') {
                    "a file beside the experiment"
                } else {
                    "on PATH"
                }
            ))
        })
    }

    /// The files whose content makes this mapper what it is: the program
    /// and every argument naming a file (a script): the input fingerprint
    /// holds their hashes, so a rebuilt mapper is never resumed stale.
    pub fn inputs(&self) -> Result<Vec<PathBuf>> {
        let mut files = vec![self.program()?];
        files.extend(
            self.command[1..]
                .iter()
                .map(PathBuf::from)
                .filter(|p| p.is_absolute() && p.is_file()),
        );
        Ok(files)
    }

    /// Runs the mapper on one run's scans and reads its map. Every failure
    /// (the command fails or outlives its timeout, no map, a map sigmap
    /// cannot read or at another resolution) is one line naming the mapper,
    /// the cell and the seed, with the end of the command's stderr.
    pub fn build(&self, run: &MapperRun) -> Result<Octree> {
        let program = self.program()?;
        let folder = PrivateFolder::new()
            .map_err(|e| self.failure(run, format!("no private folder: {e}")))?;
        let fail = |what: String| {
            // Kept for the user to look at: marked, so that no later run
            // takes it for the leftover of a killed sigmap.
            let _ = std::fs::write(folder.path.join(FAILED), format!("{what}\n"));
            self.failure(
                run,
                format!("{what} (its files: {})", folder.path.display()),
            )
        };
        let export = folder.path.join("scans");
        let dir = folder.path.join("work");
        std::fs::create_dir(&dir).map_err(|e| fail(format!("no private folder: {e}")))?;
        write_export(
            &export,
            run.view,
            run.scans,
            &MapFrame {
                resolution: run.resolution,
                offset: run.offset,
                camera: run.camera,
            },
            &format!("the run of seed {} for mapper {}", run.seed, self.name),
        )?;
        let places = Placeholders {
            scans: export.join("scans.graph"),
            poses: export.join("poses.txt"),
            plys: export.clone(),
            dir: dir.clone(),
            resolution: run.resolution,
            max_range: run.view.max_range,
            seed: run.seed,
            camera: run.camera.copied(),
        };
        let args: Vec<String> = self.command[1..].iter().map(|a| places.fill(a)).collect();
        let stderr_path = folder.path.join("stderr.txt");
        let outcome = self.run_command(
            &program,
            &args,
            &dir,
            &folder.path.join("stdout.txt"),
            &stderr_path,
        );
        let tail = stderr_tail(&stderr_path);
        let with_tail = |what: String| {
            if tail.is_empty() {
                fail(what)
            } else {
                fail(format!("{what}; its stderr ends: {tail}"))
            }
        };
        outcome.map_err(with_tail)?;
        let map_path = dir.join(places.fill(&self.map));
        if !map_path.is_file() {
            let what = if map_path.exists() {
                "its map is not a regular file:"
            } else {
                "it wrote no map at"
            };
            return Err(with_tail(format!("{what} {}", map_path.display())));
        }
        let map = read_octree(&map_path, run.clamp)
            .map_err(|e| with_tail(format!("its map is not an octree sigmap reads ({e})")))?;
        if (map.resolution() - run.resolution).abs() > 1e-9 * run.resolution {
            return Err(fail(format!(
                "its map has resolution {} m, the experiment {} m: build it at {{resolution}}",
                map.resolution(),
                run.resolution
            )));
        }
        folder.remove();
        Ok(map)
    }

    /// The one-line error of a failed run of this mapper.
    fn failure(&self, run: &MapperRun, what: String) -> Error {
        let cell = if run.cell.is_empty() {
            String::new()
        } else {
            format!("cell {}, ", run.cell)
        };
        Error::Usage(format!(
            "mapper {} ({cell}seed {}): {what}",
            self.name, run.seed
        ))
    }

    /// Runs `program args` in `dir` without a shell, its output into files,
    /// stopped after the timeout.
    fn run_command(
        &self,
        program: &Path,
        args: &[String],
        dir: &Path,
        stdout: &Path,
        stderr: &Path,
    ) -> std::result::Result<(), String> {
        use std::os::unix::process::CommandExt;
        let file = |path: &Path| std::fs::File::create(path).map_err(|e| format!("{e}"));
        // Its own process group, so that a timeout stops whatever it
        // started too (a script's children).
        let mut child = Command::new(program)
            .process_group(0)
            .args(args)
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(file(stdout)?)
            .stderr(file(stderr)?)
            .spawn()
            .map_err(|e| format!("could not start {}: {e}", program.display()))?;
        // Killed when this returns, and by a signal that stops sigmap.
        let group = stop::Group::list(child.id());
        let start = Instant::now();
        let status = loop {
            match child.try_wait() {
                Ok(Some(status)) => break status,
                Ok(None) if start.elapsed() > self.timeout => {
                    group.kill();
                    let _ = child.kill();
                    let _ = child.wait();
                    return Err(format!(
                        "still running after its timeout of {} s; stopped",
                        self.timeout.as_secs_f64()
                    ));
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(5)),
                Err(e) => return Err(format!("lost track of the command: {e}")),
            }
        };
        if status.success() {
            Ok(())
        } else {
            Err(format!("the command failed ({status})"))
        }
    }
}

/// The file that marks a kept private folder of a failed mapper run.
const FAILED: &str = "FAILED.txt";

/// The last [`STDERR_TAIL`] bytes of a command's stderr, on one line
/// without control characters; only they are read, however much the
/// command wrote.
fn stderr_tail(path: &Path) -> String {
    use std::io::{Seek, SeekFrom};
    let mut bytes = Vec::new();
    if let Ok(mut file) = std::fs::File::open(path) {
        let length = file.metadata().map_or(0, |m| m.len());
        let start = length.saturating_sub(STDERR_TAIL as u64);
        if file.seek(SeekFrom::Start(start)).is_ok() {
            let _ = file.take(STDERR_TAIL as u64).read_to_end(&mut bytes);
        }
    }
    String::from_utf8_lossy(&bytes)
        .replace(char::is_control, " ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

/// A folder of sigmap's own in the system's temporary folder, for one
/// mapper run; removed when the mapper succeeded, kept (and named in the
/// error) when it failed.
struct PrivateFolder {
    path: PathBuf,
}

impl PrivateFolder {
    fn new() -> std::io::Result<Self> {
        use std::sync::atomic::{AtomicU64, Ordering};
        static NEXT: AtomicU64 = AtomicU64::new(0);
        static CLEANED: std::sync::Once = std::sync::Once::new();
        CLEANED.call_once(remove_leftovers);
        loop {
            let n = NEXT.fetch_add(1, Ordering::Relaxed);
            let path =
                std::env::temp_dir().join(format!("sigmap-mapper-{}-{n}", std::process::id()));
            match std::fs::create_dir(&path) {
                Ok(()) => {
                    // Marked as sigmap's: only a marked folder is ever taken
                    // for a leftover and removed.
                    std::fs::write(path.join(crate::files::MARKER), "written by sigmap\n")?;
                    return Ok(Self { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
                Err(e) => return Err(e),
            }
        }
    }

    /// Removes the folder: sigmap made it, and only the run wrote in it.
    fn remove(self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// Removes the private folders a killed sigmap left (`sigmap-mapper-PID-N`
/// of a process that no longer runs, carrying sigmap's [`MARKER`] and no
/// [`FAILED`] mark); those of failed runs, named in their error, and any
/// folder sigmap did not make are left alone.
///
/// [`MARKER`]: crate::files::MARKER
fn remove_leftovers() {
    let Ok(entries) = std::fs::read_dir(std::env::temp_dir()) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = name
            .strip_prefix("sigmap-mapper-")
            .and_then(|rest| rest.split_once('-'))
            .and_then(|(pid, _)| pid.parse::<u32>().ok())
        else {
            continue;
        };
        let path = entry.path();
        let ours = path.join(crate::files::MARKER).is_file() && !path.join(FAILED).exists();
        if ours && crate::files::process_gone(pid) {
            let _ = std::fs::remove_dir_all(&path);
        }
    }
}

mod stop;
#[cfg(test)]
mod tests;
