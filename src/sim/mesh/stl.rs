//! STL files, ASCII or binary, told apart by their size rather than by
//! their first word.
//!
//! A binary STL is an 80-byte header, a little-endian `u32` triangle count
//! and 50 bytes per triangle. Many CAD exporters start that header with
//! `solid <name>`, the first word of an ASCII STL, and a reader that goes by
//! the first line takes such a file for ASCII whenever the bytes up to its
//! first newline are text (a newline in the header, or a count whose low
//! byte is 10). A file of exactly `84 + 50 n` bytes, `n` its count, is read
//! as binary whatever its header says; a longer one (an exporter's trailing
//! bytes) too, unless its first line is followed by `facet` or `endsolid`
//! as an ASCII file's is.

use super::Mesh;
use crate::error::{Error, Result};
use crate::geometry::Vector3;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// Bytes before a binary STL's first triangle.
const PREAMBLE: u64 = 84;

/// Bytes of one binary triangle: normal, three vertices, attribute count.
const TRIANGLE: u64 = 50;

/// Bytes read to tell an ASCII file: its first line and the next word.
const PROBE: u64 = 1024;

/// Whether a file that begins with `probe` is ASCII STL: `solid`, then on
/// the next line `facet` or `endsolid` (case aside). A binary header that
/// begins with `solid` is followed by a count and floats instead. A first
/// line longer than the probe leaves it to `stl_io` (ASCII if it parses).
fn is_ascii(probe: &[u8]) -> bool {
    if !probe.starts_with(b"solid") {
        return false;
    }
    let Some(newline) = probe.iter().position(|&b| b == b'\n') else {
        return true;
    };
    let next = probe[newline..].trim_ascii_start();
    let starts = |word: &[u8]| {
        next.get(..word.len())
            .is_some_and(|w| w.eq_ignore_ascii_case(word))
    };
    starts(b"facet") || starts(b"endsolid")
}

/// Reads an ASCII or binary STL file.
pub(super) fn load(path: &Path) -> Result<Mesh> {
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut probe = Vec::with_capacity(PROBE as usize);
    (&mut file)
        .take(PROBE)
        .read_to_end(&mut probe)
        .map_err(|e| Error::io(path, e))?;
    file.rewind().map_err(|e| Error::io(path, e))?;
    let count = probe
        .get(80..84)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
    let ascii = is_ascii(&probe);
    let binary_size = |n: u32| PREAMBLE + TRIANGLE * u64::from(n);
    let stl = match count {
        Some(n) if binary_size(n) == size || (!ascii && binary_size(n) < size) => {
            stl_io::read_stl(&mut BinaryHeader { file, at: 0 })
        }
        Some(n) if !ascii => {
            return Err(Error::input(
                path,
                format!(
                    "binary STL whose header counts {n} triangles ({} bytes), but the file has \
                     {size} bytes: it is cut short or its count is wrong",
                    binary_size(n)
                ),
            ));
        }
        _ => stl_io::read_stl(&mut file),
    }
    .map_err(|e| Error::input(path, format!("malformed STL: {e}")))?;
    Ok(Mesh {
        vertices: stl
            .vertices
            .iter()
            .map(|v| Vector3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
            .collect(),
        triangles: stl
            .faces
            .iter()
            .map(|f| f.vertices.map(|i| i as u32))
            .collect(),
    })
}

/// A binary STL file with its first byte read as 0, so that a header
/// beginning with `solid` does not pass for an ASCII file (the header is
/// not part of the mesh).
struct BinaryHeader {
    file: std::fs::File,
    at: u64,
}

impl Read for BinaryHeader {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read(buf)?;
        if self.at == 0 && n > 0 {
            buf[0] = 0;
        }
        self.at += n as u64;
        Ok(n)
    }
}

impl Seek for BinaryHeader {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.at = self.file.seek(to)?;
        Ok(self.at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A binary STL of a pentagonal bipyramid (10 triangles, closed,
    /// outward) with `header` padded to 80 bytes.
    fn bipyramid(header: &[u8]) -> Vec<u8> {
        let ring: Vec<[f32; 3]> = (0..5)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / 5.0;
                [a.cos(), a.sin(), 1.0]
            })
            .collect();
        let (top, bottom) = ([0.0, 0.0, 2.0], [0.0, 0.0, 0.0]);
        let mut bytes = header.to_vec();
        bytes.resize(80, b' ');
        bytes.extend(10u32.to_le_bytes());
        for i in 0..5 {
            let (a, b) = (ring[i], ring[(i + 1) % 5]);
            for triangle in [[a, b, top], [b, a, bottom]] {
                bytes.extend([0u8; 12]);
                for v in triangle {
                    bytes.extend(v.iter().flat_map(|c| c.to_le_bytes()));
                }
                bytes.extend([0u8; 2]);
            }
        }
        bytes
    }

    #[test]
    fn a_binary_file_whose_header_says_solid_is_read_as_binary() {
        let dir = tempfile::tempdir().unwrap();
        // A count of 10 is a newline: the bytes before it are all text.
        for header in [&b"solid bipyramid"[..], b"solid part\nexported", b"binary"] {
            let path = dir.path().join("part.stl");
            std::fs::write(&path, bipyramid(header)).unwrap();
            let mesh = Mesh::load(&path).unwrap();
            assert_eq!(mesh.triangles.len(), 10, "{header:?}");
            mesh.check_closed().unwrap();
            assert!(mesh.signed_volume() > 0.0);
        }
    }

    /// Bytes past the last triangle (some exporters pad the file) do not
    /// make a `solid` header pass for ASCII.
    #[test]
    fn a_binary_file_with_trailing_bytes_is_read_as_binary() {
        let dir = tempfile::tempdir().unwrap();
        for header in [&b"solid part\nexported"[..], b"solid bipyramid", b"binary"] {
            let path = dir.path().join("padded.stl");
            let mut bytes = bipyramid(header);
            bytes.extend(b"\n\0\0 trailing\n");
            std::fs::write(&path, bytes).unwrap();
            let mesh = Mesh::load(&path).unwrap();
            assert_eq!(mesh.triangles.len(), 10, "{header:?}");
            mesh.check_closed().unwrap();
        }
    }

    #[test]
    fn a_cut_short_binary_file_says_so() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cut.stl");
        for header in [&b"binary"[..], b"solid part\nexported"] {
            let mut bytes = bipyramid(header);
            bytes.truncate(300);
            std::fs::write(&path, bytes).unwrap();
            let msg = Mesh::load(&path).unwrap_err().to_string();
            assert!(
                msg.contains("cut.stl")
                    && msg.contains("counts 10 triangles")
                    && msg.contains("cut short"),
                "{msg}"
            );
        }
    }

    #[test]
    fn an_ascii_file_is_read_as_ascii() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("one.stl");
        let facet = |v: [[f32; 3]; 3]| {
            let mut s = String::from("facet normal 0 0 0\nouter loop\n");
            for p in v {
                s += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
            }
            s + "endloop\nendfacet\n"
        };
        let (o, x, y, z) = ([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let text = format!(
            "solid tetra\n{}{}{}{}endsolid tetra\n",
            facet([o, y, x]),
            facet([o, x, z]),
            facet([o, z, y]),
            facet([x, y, z])
        );
        std::fs::write(&path, text).unwrap();
        let mesh = Mesh::load(&path).unwrap();
        assert_eq!(mesh.triangles.len(), 4);
        mesh.check_closed().unwrap();
    }
}
