//! OctoMap's file formats (docs/octomap.md): `.ot` (full log-odds)
//! and `.bt` (maximum likelihood, 2 bits per child), written and read. An
//! `OcTreeStamped` or `ColorOcTree` file is read as its occupancy (its
//! colours are passed over); files are written as `OcTree`.

use super::octree::{Clamp, NodeId, Octree, DEPTH};
use crate::error::{check_input_file, Error, Result};
use std::io::{BufRead, Read};
use std::path::Path;

/// The first line of a `.ot` file.
pub(crate) const OT_HEADER: &str = "# Octomap OcTree file";
const BT_HEADER: &str = "# Octomap OcTree binary file";

/// OctoMap's occupancy test: log-odds at or above 0 (`isNodeOccupied`).
#[inline]
pub fn is_occupied(log_odds: f32) -> bool {
    log_odds >= 0.0
}

fn header(first: &str, size: usize, resolution: f64) -> String {
    typed_header(first, "", "OcTree", size, resolution)
}

/// A header for a tree of type `id`, with `comment` lines (each starting
/// with `# `) after the first line.
fn typed_header(first: &str, comment: &str, id: &str, size: usize, resolution: f64) -> String {
    format!(
        "{first}\n{comment}# (feel free to add / change comments, but leave the first line as it is!)\n#\n\
         id {id}\nsize {size}\nres {resolution}\ndata\n"
    )
}

/// OctoMap's colour of a node no one coloured (`ColorOcTreeNode::Color()`).
const WHITE: [u8; 3] = [255, 255, 255];

/// The `.ot` bytes of a `ColorOcTree` holding only `cells`: finest cells by
/// Morton code ([`Key::morton`](super::Key::morton), sorted, each once), each
/// at log-odds `value` in its own colour. No cell is pruned into its parent,
/// so neighbours keep their colours; inner nodes hold `value` (the maximum
/// of their children) and OctoMap's default colour. `comment` (lines that
/// start with `# `) goes in the header.
pub fn colour_cells_to_ot(
    resolution: f64,
    cells: &[(u64, [u8; 3])],
    value: f32,
    comment: &str,
) -> Vec<u8> {
    debug_assert!(
        cells.windows(2).all(|w| w[0].0 < w[1].0),
        "sorted, each once"
    );
    let mut body = Vec::new();
    let nodes = if cells.is_empty() {
        0
    } else {
        write_colour_node(cells, 0, value, &mut body)
    };
    let mut out = typed_header(OT_HEADER, comment, "ColorOcTree", nodes, resolution).into_bytes();
    out.extend(body);
    out
}

/// The node at `depth` holding `cells` (all of them below it) and its
/// subtree, depth first; returns its node count.
fn write_colour_node(cells: &[(u64, [u8; 3])], depth: u8, value: f32, out: &mut Vec<u8>) -> usize {
    out.extend_from_slice(&value.to_le_bytes());
    if depth == DEPTH {
        out.extend_from_slice(&cells[0].1);
        out.push(0);
        return 1;
    }
    out.extend_from_slice(&WHITE);
    // The child index at this depth: the code's next three bits from the top.
    let shift = 3 * u32::from(DEPTH - depth - 1);
    let child = |code: u64| (code >> shift & 7) as usize;
    let mask = cells
        .iter()
        .fold(0u8, |mask, &(code, _)| mask | 1 << child(code));
    out.push(mask);
    let mut nodes = 1;
    let mut rest = cells;
    while let Some(&(first, _)) = rest.first() {
        let run = rest.partition_point(|&(code, _)| child(code) == child(first));
        nodes += write_colour_node(&rest[..run], depth + 1, value, out);
        rest = &rest[run..];
    }
    nodes
}

/// Known nodes of the tree (OctoMap's `size()`).
fn count(tree: &Octree) -> usize {
    tree.stats().nodes
}

/// The `.ot` bytes of a tree: per node its `f32` log-odds then a byte whose
/// bit `i` says child `i` exists, depth first.
pub fn to_ot(tree: &Octree) -> Vec<u8> {
    let mut out = header(OT_HEADER, count(tree), tree.resolution()).into_bytes();
    let (value, children) = tree.raw(tree.root());
    if !value.is_nan() {
        write_ot_node(tree, value, children, &mut out);
    }
    out
}

/// A node (its value and first child) and what lies below it, depth first.
fn write_ot_node(tree: &Octree, value: f32, children: Option<NodeId>, out: &mut Vec<u8>) {
    out.extend_from_slice(&value.to_le_bytes());
    let Some(block) = children else {
        out.push(0);
        return;
    };
    // Each child's value is read once (a depth-15 node computes its own).
    let nodes: [(f32, Option<NodeId>); 8] = std::array::from_fn(|i| tree.raw(block.offset(i)));
    let mask = (0..8).fold(0u8, |mask, i| mask | u8::from(!nodes[i].0.is_nan()) << i);
    out.push(mask);
    for (value, children) in nodes {
        if !value.is_nan() {
            write_ot_node(tree, value, children, out);
        }
    }
}

/// The `.bt` bytes: the maximum-likelihood tree (occupied leaves at the
/// clamp maximum, free ones at the minimum), pruned, 2 bits per child.
pub fn to_bt(tree: &Octree, clamp: Clamp) -> Vec<u8> {
    let mut ml = tree.clone();
    ml.map_values(|v| if is_occupied(v) { clamp.max } else { clamp.min });
    // OctoMap does not write a childless root: give it its eight children.
    let (value, children) = ml.raw(ml.root());
    if children.is_none() && !value.is_nan() {
        let block = ml.raw_expand(ml.root());
        for i in 0..8 {
            ml.set_raw_value(block.offset(i), value);
        }
    }
    let (value, _) = ml.raw(ml.root());
    let mut out = header(
        BT_HEADER,
        if value.is_nan() { 0 } else { count(&ml) },
        ml.resolution(),
    )
    .into_bytes();
    if !value.is_nan() {
        write_bt_node(&ml, ml.root(), &mut out);
    }
    out
}

fn write_bt_node(tree: &Octree, node: NodeId, out: &mut Vec<u8>) {
    let Some(block) = tree.raw(node).1 else {
        return;
    };
    let mut bytes = [0u8; 2];
    for i in 0..8 {
        let (value, grandchildren) = tree.raw(block.offset(i));
        let code = if value.is_nan() {
            0
        } else if grandchildren.is_some() {
            3
        } else if is_occupied(value) {
            2
        } else {
            1
        };
        bytes[i / 4] |= code << (2 * (i % 4));
    }
    out.extend_from_slice(&bytes);
    for i in 0..8 {
        if tree.raw(block.offset(i)).1.is_some() {
            write_bt_node(tree, block.offset(i), out);
        }
    }
}

/// Checks that `path` names an OctoMap file (`.bt` or `.ot`), so that a
/// command can refuse it before any work.
pub fn check_octree_path(path: &Path) -> Result<()> {
    if matches!(path.extension().and_then(|e| e.to_str()), Some("bt" | "ot")) {
        Ok(())
    } else {
        Err(Error::input(path, "an octree file must end in .bt or .ot"))
    }
}

/// Writes `.ot` or `.bt` by the file's extension.
pub fn write_octree(path: &Path, tree: &Octree, clamp: Clamp) -> Result<()> {
    check_octree_path(path)?;
    let bytes = if path.extension().is_some_and(|e| e == "ot") {
        to_ot(tree)
    } else {
        to_bt(tree, clamp)
    };
    crate::files::write_file(path, &bytes)
}

/// Most bytes of a map file sigmap reads (8 GiB: a tree of about that size
/// in memory, past the 6 GiB a map may take while it is built).
pub const MAX_MAP_FILE_BYTES: u64 = 8 << 30;

/// Reads a `.ot` or `.bt` file (by its first line): a regular file of at
/// most [`MAX_MAP_FILE_BYTES`], so that a device or a pipe is refused, not
/// read forever. `.bt` leaves take the clamp bounds, as OctoMap's reader
/// gives them.
pub fn read_octree(path: &Path, clamp: Clamp) -> Result<Octree> {
    check_input_file(path, MAX_MAP_FILE_BYTES)?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&bytes, clamp).map_err(|e| Error::input(path, e))
}

/// Parses the bytes of a `.ot` or `.bt` file.
pub fn parse(bytes: &[u8], clamp: Clamp) -> std::result::Result<Octree, String> {
    let mut reader = std::io::Cursor::new(bytes);
    let binary = match header_line(&mut reader).as_deref() {
        Some(OT_HEADER) => false,
        Some(BT_HEADER) => true,
        Some(other) => return Err(format!("not an OctoMap file (first line '{other}')")),
        None => return Err("not an OctoMap file (its first line is not text)".into()),
    };
    let (mut size, mut resolution, mut id) = (None, None, None);
    loop {
        if reader.position() >= bytes.len() as u64 {
            return Err("no `data` line".into());
        }
        let Some(line) = header_line(&mut reader) else {
            return Err("a header line before `data` is not text".into());
        };
        let line = line.as_str();
        if line.starts_with('#') || line.is_empty() {
            continue;
        }
        let (word, rest) = line.split_once(' ').unwrap_or((line, ""));
        match word {
            "id" => id = Some(rest.to_string()),
            "size" => size = rest.trim().parse::<usize>().ok(),
            "res" => resolution = rest.trim().parse::<f64>().ok(),
            "data" => break,
            _ => return Err(format!("unexpected header line '{line}'")),
        }
    }
    let extra = match id.as_deref() {
        Some(id) => node_extra_bytes(id)?,
        None => return Err("no `id` line (the tree type, e.g. `id OcTree`)".into()),
    };
    let resolution = resolution
        .filter(|r| r.is_finite() && *r > 0.0)
        .ok_or("missing or bad `res` (a positive, finite cell size in metres)")?;
    let size = size.ok_or("missing or bad `size`")?;
    let mut tree = Octree::new(resolution);
    let mut body = Vec::new();
    reader.read_to_end(&mut body).map_err(|e| e.to_string())?;
    let mut cursor = 0usize;
    if size > 0 {
        let root = tree.root();
        if binary {
            tree.set_raw_value(root, 0.0);
            read_bt_node(&mut tree, root, &body, &mut cursor, clamp)?;
        } else {
            read_ot_node(&mut tree, root, (&body, &mut cursor), extra)?;
        }
    }
    if cursor != body.len() {
        return Err(format!("{} bytes left after the tree", body.len() - cursor));
    }
    let read = if size == 0 { 0 } else { count(&tree) };
    if read != size {
        return Err(format!("header says {size} nodes, the data holds {read}"));
    }
    Ok(tree)
}

/// The next header line without its line end; `None` when it is not text
/// (UTF-8).
fn header_line(reader: &mut std::io::Cursor<&[u8]>) -> Option<String> {
    let mut line = Vec::new();
    // Reading from memory cannot fail.
    reader.read_until(b'\n', &mut line).ok()?;
    let line = String::from_utf8(line).ok()?;
    Some(line.trim_end().to_string())
}

/// A file whose tree goes deeper than OctoMap's 16 levels.
const BELOW_FINEST: &str = "a node has children below the finest level (depth 16)";

fn take<'a>(body: &'a [u8], cursor: &mut usize, n: usize) -> std::result::Result<&'a [u8], String> {
    let slice = body
        .get(*cursor..*cursor + n)
        .ok_or("the data ends early")?;
    *cursor += n;
    Ok(slice)
}

/// The bytes a `.ot` node of tree type `id` holds after its log-odds: none
/// for `OcTree` and `OcTreeStamped` (OctoMap writes no time stamp), a colour
/// (r, g, b) for `ColorOcTree`. Their `.bt` bodies are all alike. Other
/// types are refused by name.
fn node_extra_bytes(id: &str) -> std::result::Result<usize, String> {
    match id {
        "OcTree" | "OcTreeStamped" => Ok(0),
        "ColorOcTree" => Ok(3),
        other => Err(format!(
            "tree type `{other}` is not an occupancy tree sigmap reads (OcTree, OcTreeStamped, ColorOcTree)"
        )),
    }
}

/// A `.ot` node (its log-odds, then `extra` bytes sigmap does not keep, then
/// its child mask) and what lies below it.
fn read_ot_node(
    tree: &mut Octree,
    node: NodeId,
    (body, cursor): (&[u8], &mut usize),
    extra: usize,
) -> std::result::Result<(), String> {
    let value = f32::from_le_bytes(
        take(body, cursor, 4)?
            .try_into()
            .map_err(|_| "short value")?,
    );
    tree.set_raw_value(node, value);
    take(body, cursor, extra)?;
    let mask = take(body, cursor, 1)?[0];
    if mask != 0 {
        if node.depth() == DEPTH {
            return Err(BELOW_FINEST.into());
        }
        let block = tree.raw_expand(node);
        for i in 0..8 {
            if mask & (1 << i) != 0 {
                read_ot_node(tree, block.offset(i), (body, &mut *cursor), extra)?;
            }
        }
    }
    Ok(())
}

fn read_bt_node(
    tree: &mut Octree,
    node: NodeId,
    body: &[u8],
    cursor: &mut usize,
    clamp: Clamp,
) -> std::result::Result<(), String> {
    let bytes = take(body, cursor, 2)?;
    let codes: [u8; 8] = std::array::from_fn(|i| (bytes[i / 4] >> (2 * (i % 4))) & 3);
    if node.depth() == DEPTH {
        return Err(BELOW_FINEST.into());
    }
    let block = tree.raw_expand(node);
    for (i, code) in codes.iter().enumerate() {
        match code {
            1 => tree.set_raw_value(block.offset(i), clamp.min),
            2 => tree.set_raw_value(block.offset(i), clamp.max),
            3 => {
                tree.set_raw_value(block.offset(i), clamp.min);
                read_bt_node(tree, block.offset(i), body, cursor, clamp)?;
            }
            _ => {}
        }
    }
    // Inner value: the max of the children, as OctoMap's reader computes it.
    let max = (0..8)
        .map(|i| tree.raw(block.offset(i)).0)
        .filter(|v| !v.is_nan())
        .fold(f32::NAN, f32::max);
    tree.set_raw_value(node, max);
    Ok(())
}

#[cfg(test)]
mod tests;
