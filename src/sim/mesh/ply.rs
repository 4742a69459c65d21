//! PLY meshes (the Stanford format: scanned objects, MeshLab, Open3D,
//! CloudCompare), ASCII or binary of either byte order, read by `ply-rs`.
//!
//! The `vertex` element gives the positions (`x`, `y`, `z`, any numeric
//! type); the `face` element the polygons (`vertex_indices`, or
//! `vertex_index` as some writers name it: a list of any integer type).
//! A polygon of more than three corners is cut into a fan from its first
//! corner, as OBJ polygons are. Other elements and properties (normals,
//! colours, texture coordinates, edges) are read past.
//!
//! \[DESIGN\] The parser holds every element of a kind at once, so each
//! element count is checked against the file's size first: an element
//! takes at least its scalars' bytes (binary) or two characters a scalar
//! (ASCII), a face at least three indices. A header that promises more than
//! the file can hold is refused before anything is read.

use super::Mesh;
use crate::error::{Error, Result};
use crate::geometry::Vector3;
use ply_rs::parser::Parser;
use ply_rs::ply::{
    ElementDef, Encoding, Header, Property, PropertyAccess, PropertyType, ScalarType,
};
use std::io::{BufRead, BufReader, Seek};
use std::path::Path;

/// Most vertices, faces or triangles read from one file (a few hundred MB
/// of polygons, as [`super::MAX_MESH_BYTES`] allows an STL file).
pub(super) const MAX_PLY_ELEMENTS: usize = 10_000_000;

/// The names a `face` element's list of corners goes by.
const CORNERS: [&str; 2] = ["vertex_indices", "vertex_index"];

/// Whether a `face` property named `name` lists its corners.
fn is_corners(name: &str) -> bool {
    CORNERS.contains(&name)
}

/// A `vertex` element's position; a coordinate not given stays NaN.
struct Vertex([f64; 3]);

/// A `face` element's corners (vertex indices); `None`: an index is
/// negative or not an integer.
struct Face(Option<Vec<u32>>);

/// Any other element, read past.
struct Skipped;

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex([f64::NAN; 3])
    }

    fn set_property(&mut self, name: String, property: Property) {
        let axis = match name.as_str() {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return,
        };
        if let Some(value) = scalar(&property) {
            self.0[axis] = value;
        }
    }
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face(Some(Vec::new()))
    }

    fn set_property(&mut self, name: String, property: Property) {
        if !is_corners(&name) {
            return;
        }
        fn all<T: Copy>(list: &[T], index: impl Fn(T) -> Option<u32>) -> Option<Vec<u32>> {
            list.iter().map(|&i| index(i)).collect()
        }
        self.0 = match property {
            Property::ListChar(l) => all(&l, |i| u32::try_from(i).ok()),
            Property::ListUChar(l) => all(&l, |i| Some(u32::from(i))),
            Property::ListShort(l) => all(&l, |i| u32::try_from(i).ok()),
            Property::ListUShort(l) => all(&l, |i| Some(u32::from(i))),
            Property::ListInt(l) => all(&l, |i| u32::try_from(i).ok()),
            Property::ListUInt(l) => Some(l),
            _ => None,
        };
    }
}

impl PropertyAccess for Skipped {
    fn new() -> Self {
        Skipped
    }
}

/// A scalar property as a number (a list: `None`).
fn scalar(property: &Property) -> Option<f64> {
    Some(match *property {
        Property::Char(v) => f64::from(v),
        Property::UChar(v) => f64::from(v),
        Property::Short(v) => f64::from(v),
        Property::UShort(v) => f64::from(v),
        Property::Int(v) => f64::from(v),
        Property::UInt(v) => f64::from(v),
        Property::Float(v) => f64::from(v),
        Property::Double(v) => v,
        _ => return None,
    })
}

/// Bytes of one scalar of `kind`.
fn scalar_bytes(kind: &ScalarType) -> u64 {
    match kind {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The fewest bytes one `element` can take in a file of `encoding`: its
/// scalars, a list's length, and a face's three corners.
fn least_bytes(element: &ElementDef, encoding: &Encoding) -> u64 {
    let face = element.name == "face";
    element
        .properties
        .values()
        .map(|p| {
            let corners = face && is_corners(&p.name);
            let entries = if corners { 3 } else { 0 };
            match (&p.data_type, encoding) {
                (PropertyType::Scalar(_), Encoding::Ascii) => 2,
                (PropertyType::List(..), Encoding::Ascii) => 2 * (1 + entries),
                (PropertyType::Scalar(kind), _) => scalar_bytes(kind),
                (PropertyType::List(count, item), _) => {
                    scalar_bytes(count) + entries * scalar_bytes(item)
                }
            }
        })
        .sum()
}

/// Checks the header: a `vertex` element with `x`, `y`, `z`, a `face`
/// element with its corners, and no count beyond the limit or the file
/// (the elements' least bytes added up in the file's order).
fn check_header(header: &Header, size: u64, limit: usize) -> std::result::Result<(), String> {
    let element = |name: &str| header.elements.get(name);
    let vertex = element("vertex").ok_or("the PLY file has no `vertex` element")?;
    for axis in ["x", "y", "z"] {
        if !vertex.properties.contains_key(axis) {
            return Err(format!("its vertices have no `{axis}` property"));
        }
    }
    let face = element("face").ok_or(
        "the PLY file has no `face` element: it is a point cloud, not a mesh \
         (a scene object needs a closed triangle surface)",
    )?;
    if !CORNERS
        .iter()
        .any(|name| face.properties.contains_key(*name))
    {
        return Err("its faces have no `vertex_indices` list".into());
    }
    let mut least = 0;
    for element in header.elements.values() {
        if element.count > limit {
            return Err(format!(
                "its header counts {} elements `{}`; sigmap reads at most {limit} \
                 (simplify the mesh)",
                element.count, element.name
            ));
        }
        least += least_bytes(element, &header.encoding) * element.count as u64;
        if least > size {
            return Err(format!(
                "its header counts {} elements `{}`, which with those before them take at \
                 least {least} bytes, but the file has {size} bytes: it is cut short or a \
                 count is wrong",
                element.count, element.name
            ));
        }
    }
    Ok(())
}

/// What `ply-rs` found wrong in `part` of the file, on one line: a file
/// that ends early says so; otherwise the first line of its message.
fn unreadable(part: &str, e: &std::io::Error) -> String {
    let message = e.to_string();
    if e.kind() == std::io::ErrorKind::UnexpectedEof || message.contains("UnexpectedEof") {
        return format!(
            "the file ends within its `{part}` elements: it is cut short or a count is wrong"
        );
    }
    let first = message.lines().next().unwrap_or_default();
    // In the body `ply-rs` counts the part's elements from 0 as "Line".
    match first.strip_prefix("Line ").and_then(|l| l.split_once(": ")) {
        Some((index, what)) if part != "header" => {
            let what = what.replace("Couln't", "Couldn't");
            format!("malformed PLY: `{part}` element {index}: {what}")
        }
        _ => format!("malformed PLY ({part}): {first}"),
    }
}

/// Checks that every number of the header's `element` and `format` lines
/// fits in 64 bits, which `ply-rs` assumes (it panics on a longer one).
fn check_header_numbers(reader: &mut impl BufRead) -> std::result::Result<(), String> {
    let mut line = Vec::new();
    loop {
        line.clear();
        match reader.read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => return Ok(()),
            Ok(_) => {}
        }
        let text = String::from_utf8_lossy(&line);
        let words: Vec<&str> = text.split_whitespace().collect();
        match words.first().copied() {
            Some("end_header") => return Ok(()),
            Some("element" | "format") => {
                let too_long = words
                    .iter()
                    .flat_map(|w| w.split('.'))
                    .find(|w| w.len() > 19 && w.bytes().all(|b| b.is_ascii_digit()));
                if let Some(number) = too_long {
                    return Err(format!(
                        "its header line `{} …` holds the number {}…, past any count a file \
                         can hold",
                        words[..2.min(words.len())].join(" "),
                        &number[..12]
                    ));
                }
            }
            _ => {}
        }
    }
}

/// Reads a PLY mesh.
pub(super) fn load(path: &Path) -> Result<Mesh> {
    load_at_most(path, MAX_PLY_ELEMENTS)
}

/// [`load`] with at most `limit` vertices, faces and triangles.
fn load_at_most(path: &Path, limit: usize) -> Result<Mesh> {
    let bad = |what: String| Error::input(path, what);
    let malformed = |part: &str| {
        let part = part.to_owned();
        move |e: std::io::Error| Error::input(path, unreadable(&part, &e))
    };
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut reader = BufReader::new(file);
    check_header_numbers(&mut reader).map_err(bad)?;
    reader.rewind().map_err(|e| Error::io(path, e))?;
    let header = Parser::<Skipped>::new()
        .read_header(&mut reader)
        .map_err(malformed("header"))?;
    check_header(&header, size, limit).map_err(bad)?;
    let mut mesh = Mesh::default();
    for element in header.elements.values() {
        match element.name.as_str() {
            "vertex" => {
                let vertices = Parser::<Vertex>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(malformed(&element.name))?;
                mesh.vertices = vertices.iter().map(|v| Vector3::from(v.0)).collect();
            }
            "face" => {
                let faces = Parser::<Face>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(malformed(&element.name))?;
                for (k, face) in faces.into_iter().enumerate() {
                    let corners = face.0.ok_or_else(|| {
                        bad(format!(
                            "face {k} has a negative or non-integer vertex index"
                        ))
                    })?;
                    if corners.len() < 3 {
                        return Err(bad(format!(
                            "face {k} has {} corners; a face needs at least 3",
                            corners.len()
                        )));
                    }
                    if mesh.triangles.len() + corners.len() - 2 > limit {
                        return Err(bad(format!(
                            "its faces make more than {limit} triangles \
                             (simplify the mesh)"
                        )));
                    }
                    mesh.triangles.extend(
                        (1..corners.len() - 1).map(|i| [corners[0], corners[i], corners[i + 1]]),
                    );
                }
            }
            _ => {
                Parser::<Skipped>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(malformed(&element.name))?;
            }
        }
    }
    let count = mesh.vertices.len();
    if let Some(i) = mesh
        .triangles
        .iter()
        .flatten()
        .find(|&&i| i as usize >= count)
    {
        return Err(bad(format!(
            "a face uses vertex {i}, but the file has {count} vertices"
        )));
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests;
