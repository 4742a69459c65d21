//! Errors and exit codes.
//!
//! Every failure a user can cause (a missing file, malformed TOML or URDF, a
//! negative sigma, an unreachable viewpoint) is an [`Error::Input`] that names
//! the file and what is wrong; the binary maps it to exit code 2. A failed check
//! (a regression) is exit code 1. A panic is a bug.

use std::fmt;
use std::path::{Path, PathBuf};

/// The crate's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong, and whose fault it is.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad input: the file (or `-` for the command line) and a message that says
    /// what is wrong and, where it can, what to do.
    #[error("{}: {message}", path.display())]
    Input {
        /// The file at fault (`-`: the command line).
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// Bad command-line usage.
    #[error("{0}")]
    Usage(String),
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file read or written.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// A check ran and failed (a regression, an inconsistent covariance).
    #[error("{0}")]
    CheckFailed(String),
    /// sigmap itself failed (a poisoned lock, a value it cannot serialise):
    /// a bug, not the input's fault.
    #[error("internal error (a bug in sigmap; please report it): {0}")]
    Internal(String),
}

/// The exit code of an internal failure (an [`Error::Internal`] or a
/// panic).
pub const EXIT_INTERNAL: i32 = 3;

impl Error {
    /// A bad-input error about `path`.
    pub fn input(path: impl AsRef<Path>, message: impl fmt::Display) -> Self {
        Error::Input {
            path: path.as_ref().to_path_buf(),
            message: message.to_string(),
        }
    }

    /// An I/O error on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }

    /// The process exit code: 1 for a failed check, 2 for anything the user
    /// must fix (input, usage, files), [`EXIT_INTERNAL`] for sigmap's own
    /// failure.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::CheckFailed(_) => 1,
            Error::Input { .. } | Error::Usage(_) | Error::Io { .. } => 2,
            Error::Internal(_) => EXIT_INTERNAL,
        }
    }

    /// Prefixes the message of an input or usage error with more context
    /// (`"viewpoint 3: "`; the command line's flag), keeping its file.
    pub fn context(self, prefix: impl fmt::Display) -> Self {
        match self {
            Error::Input { path, message } => Error::Input {
                path,
                message: format!("{prefix}{message}"),
            },
            Error::Usage(message) => Error::Usage(format!("{prefix}{message}")),
            other => other,
        }
    }

    /// Appends what to do to the message of an input or usage error (the
    /// command line's flags, which the library does not know).
    pub fn hint(self, hint: impl fmt::Display) -> Self {
        match self {
            Error::Input { path, message } => Error::Input {
                path,
                message: format!("{message} ({hint})"),
            },
            Error::Usage(message) => Error::Usage(format!("{message} ({hint})")),
            other => other,
        }
    }
}

/// Checks that `path` is a regular file (a symlink to one is fine) of at
/// most `max_bytes`, before anything reads it: a device such as `/dev/zero`
/// or a huge file is refused, not read forever.
pub fn check_input_file(path: &Path, max_bytes: u64) -> Result<()> {
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::input(path, "file not found"),
        _ => Error::io(path, e),
    })?;
    if !meta.is_file() {
        return Err(Error::input(path, "is not a regular file"));
    }
    if meta.len() > max_bytes {
        return Err(Error::input(
            path,
            format!(
                "is {} MB; sigmap reads input files of at most {} MB",
                meta.len() >> 20,
                max_bytes >> 20
            ),
        ));
    }
    Ok(())
}

/// A length (m) for a message: as given, or in exponent form where it is
/// absurd (`1e100`, not a hundred digits).
pub fn metres(x: f64) -> String {
    if (1e-6..1e6).contains(&x.abs()) || x == 0.0 {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// Most bytes of a text input (URDF, CSV).
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// Most bytes of a TOML file (an experiment, scene, profile or manifest).
/// A parsed TOML document takes about 16 times its text, so this bounds the
/// parse at about 64 MB; the largest experiment sigmap runs (10 000
/// viewpoints) fits in about 1 MB.
pub const MAX_TOML_BYTES: u64 = 4 << 20;

/// Reads a whole text file (at most [`MAX_TEXT_BYTES`]), naming it on failure.
pub fn read_text(path: &Path) -> Result<String> {
    check_input_file(path, MAX_TEXT_BYTES)?;
    std::fs::read_to_string(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::input(path, "file not found"),
        std::io::ErrorKind::InvalidData => Error::input(path, "is not UTF-8 text"),
        _ => Error::io(path, e),
    })
}

/// A TOML error on one line: where, and what.
fn toml_error(text: &str, e: &toml::de::Error) -> String {
    let message = e.message().trim().replace('\n', " ");
    match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
            format!("malformed TOML at line {line}, column {column}: {message}")
        }
        None => format!("malformed TOML: {message}"),
    }
}

/// Parses a TOML file into `T`, naming the file and the offending line on failure.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    read_toml_with(path, &[])
}

/// Parses a TOML file into `T` after setting fields: each override is a
/// dotted path (`sensor.max_range`, `world_from_robot.sigma.3`, `scene`) and
/// the value it takes. The path must name an existing number (for a number)
/// or string (for a string).
pub fn read_toml_with<T: serde::de::DeserializeOwned>(
    path: &Path,
    overrides: &[(String, toml::Value)],
) -> Result<T> {
    check_input_file(path, MAX_TOML_BYTES).map_err(|e| match e {
        Error::Input { path, .. } if path.is_file() => Error::input(
            &path,
            format!(
                "is {:.1} MB; a TOML input holds at most {} MB (10 000 viewpoints, the most a \
                 run takes, fit in about 1 MB)",
                std::fs::metadata(&path).map_or(0.0, |m| m.len() as f64 / f64::from(1 << 20)),
                MAX_TOML_BYTES >> 20
            ),
        ),
        other => other,
    })?;
    let text = read_text(path)?;
    if overrides.is_empty() {
        // Straight from the text, so that errors carry their line.
        return toml::from_str(&text).map_err(|e| Error::input(path, toml_error(&text, &e)));
    }
    let mut value: toml::Value =
        toml::from_str(&text).map_err(|e| Error::input(path, toml_error(&text, &e)))?;
    for (field, new) in overrides {
        set_value(&mut value, field, new).map_err(|e| Error::input(path, e))?;
    }
    value.try_into().map_err(|e: toml::de::Error| {
        Error::input(
            path,
            format!("malformed TOML: {}", e.message().trim().replace('\n', " ")),
        )
    })
}

fn set_value(
    value: &mut toml::Value,
    field: &str,
    new: &toml::Value,
) -> std::result::Result<(), String> {
    let mut slot = value;
    for part in field.split('.') {
        slot = match slot {
            toml::Value::Table(t) => t.get_mut(part),
            toml::Value::Array(a) => part.parse::<usize>().ok().and_then(|i| a.get_mut(i)),
            _ => None,
        }
        .ok_or_else(|| {
            format!("sweep field '{field}': no '{part}' here (set it in the file to sweep it)")
        })?;
    }
    match (&*slot, new) {
        (toml::Value::Float(_) | toml::Value::Integer(_), toml::Value::Float(f)) => {
            *slot = if slot.is_integer() && f.fract() == 0.0 {
                toml::Value::Integer(*f as i64)
            } else {
                toml::Value::Float(*f)
            }
        }
        (toml::Value::Float(_) | toml::Value::Integer(_), toml::Value::Integer(i)) => {
            *slot = if slot.is_integer() {
                toml::Value::Integer(*i)
            } else {
                toml::Value::Float(*i as f64)
            }
        }
        // A word, or a setting that is a word or a number (`risk = "off"`
        // swept over levels): the experiment's schema checks what the sweep
        // put there.
        (toml::Value::String(_), toml::Value::String(_) | toml::Value::Float(_)) => {
            *slot = new.clone();
        }
        _ => {
            return Err(format!(
                "sweep field '{field}' holds {}, the sweep gives {}",
                slot.type_str(),
                new.type_str()
            ))
        }
    }
    Ok(())
}
