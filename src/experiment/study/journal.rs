//! What makes a resumed run trustworthy: the journal of finished runs, whose
//! records are either whole or ignored, and the fingerprint of every input a
//! run read, so that results of other inputs are never reused.

use crate::error::{Error, Result};
use crate::experiment::run::runner::{RunRow, TimingRow};
use crate::experiment::Experiment;
use crate::experiment::RunMethod;
use sha2::{Digest, Sha256};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// FNV-1a, 64 bits: the journal's check that a record is whole (a torn
/// write, not a forgery, is what it guards against).
fn fnv(hash: u64, bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(hash, |h, b| (h ^ *b as u64).wrapping_mul(0x100_0000_01b3))
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// The prefix of a fingerprint sigmap trusts; a results folder whose
/// `run.toml` holds another (the FNV-1a checksums of older versions) is
/// refused on resume.
pub const FINGERPRINT_SCHEME: &str = "sha256:";

/// What the runs of an experiment read: one SHA-256 over everything, and one
/// per input file (to say which changed).
#[derive(Clone, Debug, PartialEq)]
pub struct Inputs {
    /// `sha256:` and the SHA-256 of sigmap's version, every cell's sweep
    /// values and every file's length and bytes.
    pub fingerprint: String,
    /// Each file read (in first-use order, once) and its hash.
    pub files: Vec<(String, String)>,
}

impl Inputs {
    /// The files whose hash differs from `recorded` (or that one side lacks).
    pub fn changed_since(&self, recorded: &[(String, String)]) -> Vec<String> {
        let mut changed: Vec<String> = self
            .files
            .iter()
            .filter(|f| !recorded.contains(f))
            .map(|(p, _)| p.clone())
            .collect();
        changed.extend(
            recorded
                .iter()
                .filter(|(p, _)| !self.files.iter().any(|(q, _)| q == p))
                .map(|(p, _)| format!("{p} (no longer read)")),
        );
        changed
    }
}

/// The inputs of the runs of `cells` (one loaded experiment per sweep
/// cell): each cell's sweep values, experiment, profile, scene and mesh
/// files and robot description, its external mappers' programs and
/// scripts, and sigmap's version. Fails when a mapper's program is missing.
pub fn fingerprint(cells: &[Experiment]) -> Result<Inputs> {
    let mut hash = Sha256::new();
    // Each field framed by its length: no two inputs hash alike by moving
    // bytes from one field to the next.
    let field = |hash: &mut Sha256, bytes: &[u8]| {
        hash.update((bytes.len() as u64).to_le_bytes());
        hash.update(bytes);
    };
    field(&mut hash, env!("CARGO_PKG_VERSION").as_bytes());
    let mut files: Vec<(String, String)> = Vec::new();
    for cell in cells {
        field(&mut hash, Experiment::cell_label(cell.cell()).as_bytes());
        let mut paths: Vec<PathBuf> = [cell.source(), &cell.profile().source, &cell.robot().source]
            .into_iter()
            .chain(cell.scene().inputs.iter().map(PathBuf::as_path))
            .map(Path::to_path_buf)
            .collect();
        // The profile the maps are told, when `[believed]` names one.
        if cell.believed().profile.is_some() {
            paths.push(cell.believed_profile().source.clone());
        }
        // An external mapper is its program and the scripts it names: a
        // rebuilt one is new input.
        for method in cell.methods() {
            if let RunMethod::External(mapper) = method {
                paths.extend(mapper.inputs()?);
            }
        }
        for path in &paths {
            // Content only: the same files named from another folder match.
            let name = path.to_string_lossy().into_owned();
            let digest = hash_file(path, &mut hash)?;
            if !files.iter().any(|(p, _)| *p == name) {
                files.push((name, hex(&digest)));
            }
        }
    }
    Ok(Inputs {
        fingerprint: format!("{FINGERPRINT_SCHEME}{}", hex(&hash.finalize())),
        files,
    })
}

/// Feeds the file at `path` to `hash` as a field (its length, then its
/// bytes, as `fingerprint` frames every field) and returns its own SHA-256,
/// reading it in blocks: a mapper's program or a model file it names may be
/// larger than memory.
fn hash_file(path: &Path, hash: &mut Sha256) -> Result<Vec<u8>> {
    use std::io::Read as _;
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let length = file.metadata().map_err(|e| Error::io(path, e))?.len();
    hash.update(length.to_le_bytes());
    let (mut own, mut read, mut block) = (Sha256::new(), 0u64, vec![0u8; 1 << 16]);
    loop {
        let n = file.read(&mut block).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        hash.update(&block[..n]);
        own.update(&block[..n]);
        read += n as u64;
    }
    if read != length {
        return Err(Error::input(
            path,
            format!("changed while it was read ({length} bytes, then {read}); run again"),
        ));
    }
    Ok(own.finalize().to_vec())
}

/// Lower-case hex of a digest.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// What an experiment asks for: its sweep cells (labels), seeds and methods.
/// Rows read back from a results folder are checked against it.
pub struct Wanted<'a> {
    /// The sweep cells' labels.
    pub cells: &'a [String],
    /// The seeds.
    pub seeds: &'a [u64],
    /// The methods.
    pub methods: &'a [RunMethod],
}

/// A row of a results file: the run and method it belongs to.
pub trait RunKey {
    /// Its (cell label, seed, method).
    fn key(&self) -> (&str, u64, &str);
}

impl RunKey for RunRow {
    fn key(&self) -> (&str, u64, &str) {
        (&self.cell, self.seed, &self.method)
    }
}

impl RunKey for TimingRow {
    fn key(&self) -> (&str, u64, &str) {
        (&self.cell, self.seed, &self.method)
    }
}

impl Wanted<'_> {
    /// Keeps the rows of runs and methods the experiment has, each
    /// (cell, seed, method) once (the first).
    pub fn keep<T: RunKey>(&self, rows: &mut Vec<T>) {
        let mut seen = BTreeSet::new();
        rows.retain(|r| {
            let (cell, seed, method) = r.key();
            self.cells.iter().any(|c| c == cell)
                && self.seeds.contains(&seed)
                && self.methods.iter().any(|m| m.as_str() == method)
                && seen.insert((cell.to_string(), seed, method.to_string()))
        });
    }

    /// The runs (cell label, seed) of `rows` (as [`Wanted::keep`] leaves
    /// them) that have a row for every method.
    pub fn complete(&self, rows: &[RunRow]) -> BTreeSet<(String, u64)> {
        let mut per_run = BTreeMap::<(&str, u64), usize>::new();
        for r in rows {
            *per_run.entry((&r.cell, r.seed)).or_default() += 1;
        }
        per_run
            .into_iter()
            .filter(|(_, n)| *n == self.methods.len())
            .map(|((cell, seed), _)| (cell.to_string(), seed))
            .collect()
    }
}

/// The journal record of one finished run: its rows as CSV lines, a
/// `#timings` line, its timing rows, then `#end <rows> <hash>`. A record cut
/// short (a kill, a full disk) has no end line or a hash that does not
/// match, and is ignored whole when read.
pub fn journal_record(rows: &[RunRow], timings: &[TimingRow]) -> Result<Vec<u8>> {
    let mut text = csv_lines(rows)?;
    text.extend_from_slice(TIMINGS);
    text.extend_from_slice(&csv_lines(timings)?);
    let end = format!("#end {} {:016x}\n", rows.len(), fnv(FNV_OFFSET, &text));
    text.extend_from_slice(end.as_bytes());
    Ok(text)
}

const TIMINGS: &[u8] = b"#timings\n";

fn csv_lines<T: serde::Serialize>(rows: &[T]) -> Result<Vec<u8>> {
    let mut text = Vec::new();
    let bad =
        |e: &dyn std::fmt::Display| Error::Internal(format!("cannot write a journal row: {e}"));
    {
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(&mut text);
        for r in rows {
            w.serialize(r).map_err(|e| bad(&e))?;
        }
        w.flush().map_err(|e| bad(&e))?;
    }
    Ok(text)
}

/// The rows and timings of every whole record of a journal (none if it
/// does not exist).
pub fn read_journal(path: &Path) -> Result<(Vec<RunRow>, Vec<TimingRow>)> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok((Vec::new(), Vec::new())),
        Err(e) => return Err(Error::io(path, e)),
    };
    let (mut rows, mut timings) = (Vec::new(), Vec::new());
    let mut start = 0;
    let mut line_start = 0;
    while line_start < bytes.len() {
        let Some(len) = bytes[line_start..].iter().position(|b| *b == b'\n') else {
            break; // a last line without its newline: cut short
        };
        let line = &bytes[line_start..line_start + len];
        let next = line_start + len + 1;
        if let Some(end) = line.strip_prefix(b"#end ") {
            if let Some((r, t)) = parse_record(&bytes[start..line_start], end) {
                rows.extend(r);
                timings.extend(t);
            }
            start = next;
        }
        line_start = next;
    }
    Ok((rows, timings))
}

fn parse_lines<T: serde::de::DeserializeOwned>(text: &[u8]) -> Option<Vec<T>> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(text)
        .deserialize()
        .collect::<std::result::Result<_, _>>()
        .ok()
}

/// The rows and timings of one record if its end line `<rows> <hash>`
/// vouches for it.
fn parse_record(record: &[u8], end: &[u8]) -> Option<(Vec<RunRow>, Vec<TimingRow>)> {
    let end = std::str::from_utf8(end).ok()?;
    let (count, hash) = end.trim().split_once(' ')?;
    let count: usize = count.parse().ok()?;
    if u64::from_str_radix(hash, 16).ok()? != fnv(FNV_OFFSET, record) {
        return None;
    }
    let split = record
        .windows(TIMINGS.len())
        .position(|w| w == TIMINGS)
        .filter(|&i| i == 0 || record[i - 1] == b'\n')?;
    let rows: Vec<RunRow> = parse_lines(&record[..split])?;
    let timings: Vec<TimingRow> = parse_lines(&record[split + TIMINGS.len()..])?;
    (rows.len() == count).then_some((rows, timings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::Method;

    /// A file read in blocks hashes as the whole file did (its length, then
    /// its bytes, in the fingerprint; its own digest beside), so results
    /// folders fingerprinted before stay valid: several blocks and a part.
    #[test]
    fn a_file_hashed_in_blocks_hashes_as_the_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("model.bin");
        let bytes: Vec<u8> = (0..200_003u32)
            .map(|i: u32| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        std::fs::write(&path, &bytes).unwrap();
        let mut streamed = Sha256::new();
        let digest = hash_file(&path, &mut streamed).unwrap();
        let mut whole = Sha256::new();
        whole.update((bytes.len() as u64).to_le_bytes());
        whole.update(&bytes);
        assert_eq!(streamed.finalize(), whole.finalize());
        assert_eq!(digest, Sha256::digest(&bytes).to_vec());
    }

    fn row(seed: u64, method: &str, f1: f64) -> RunRow {
        let mut r: RunRow = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(
                "c,1,m,0.01,10,5,0.5,0.5,0.5,0.5,0.1,0.1,0.1,0.1,0.1,0.1,0.9,3,2.9,3.1,3,0.2,0.7,0.97,10,100\n"
                    .as_bytes(),
            )
            .deserialize()
            .next()
            .unwrap()
            .unwrap();
        r.seed = seed;
        r.method = method.into();
        r.set("f1", f1);
        r
    }

    #[test]
    fn a_record_cut_anywhere_is_dropped_whole_and_the_others_kept() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("runs.journal.csv");
        let timing = |seed| TimingRow {
            cell: "c".into(),
            seed,
            method: "a".into(),
            simulate_s: 1.5,
            model_s: 0.25,
            score_s: 0.125,
        };
        let first =
            journal_record(&[row(1, "a", 0.1234567), row(1, "b", 0.5)], &[timing(1)]).unwrap();
        let second =
            journal_record(&[row(2, "a", 0.7654321), row(2, "b", 0.25)], &[timing(2)]).unwrap();
        let whole = [first.clone(), second.clone()].concat();
        std::fs::write(&path, &whole).unwrap();
        let (rows, timings) = read_journal(&path).unwrap();
        assert_eq!((rows.len(), timings.len()), (4, 2));
        assert_eq!(timings[1], timing(2));
        // Every cut inside the second record keeps exactly the first one.
        for cut in first.len()..whole.len() {
            std::fs::write(&path, &whole[..cut]).unwrap();
            let (rows, timings) = read_journal(&path).unwrap();
            assert_eq!((rows.len(), timings.len()), (2, 1), "cut at byte {cut}");
            assert!(rows.iter().all(|r| r.seed == 1) && timings[0].seed == 1);
        }
        // A digit changed in place (a torn sector) fails the hash.
        let mut bad = whole.clone();
        let at = first.len() + 30;
        bad[at] = if bad[at] == b'9' { b'8' } else { b'9' };
        std::fs::write(&path, &bad).unwrap();
        assert!(read_journal(&path).unwrap().0.iter().all(|r| r.seed == 1));
        assert!(read_journal(&dir.path().join("absent.csv"))
            .unwrap()
            .0
            .is_empty());
    }

    #[test]
    fn only_the_experiments_runs_count_and_only_when_every_method_ran() {
        let cells = ["c".to_string()];
        let methods = [Method::Unscented, Method::RayUpdate].map(RunMethod::Own);
        let wanted = Wanted {
            cells: &cells,
            seeds: &[1, 2],
            methods: &methods,
        };
        let mut rows = vec![
            row(1, "unscented", 0.1),
            row(1, "ray_update", 0.2),
            row(1, "ray_update", 0.9), // a repeat: the first stays
            row(2, "unscented", 0.3),  // seed 2 lacks the ray update
            row(3, "unscented", 0.4),  // not a seed of the experiment
            row(1, "blind", 0.5),      // not a method of the experiment
        ];
        let mut other_cell = row(1, "unscented", 0.6);
        other_cell.cell = "d".into();
        rows.push(other_cell);
        wanted.keep(&mut rows);
        let kept: Vec<(u64, &str, f64)> = rows
            .iter()
            .map(|r| (r.seed, r.method.as_str(), r.get("f1")))
            .collect();
        assert_eq!(
            kept,
            [
                (1, "unscented", 0.1),
                (1, "ray_update", 0.2),
                (2, "unscented", 0.3)
            ]
        );
        let done: Vec<_> = wanted.complete(&rows).into_iter().collect();
        assert_eq!(done, [("c".to_string(), 1)]);
    }
}
