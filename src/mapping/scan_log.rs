//! The plain-text scan log that OctoMap's `log2graph` turns into a ScanGraph
//! (docs/octomap.md), read directly: any pipeline can write it, and sigmap
//! maps it without OctoMap's tools.
//!
//! ```text
//! # a comment
//! NODE x y z roll pitch yaw      the sensor's pose in the map frame (m, rad;
//! x y z                          R = Rz(yaw) Ry(pitch) Rx(roll), as URDF)
//! x y z                          one point per line, in the sensor frame
//! NODE ...
//! ```
//!
//! As `log2graph` reads it, a line starting with `#` or a space is skipped,
//! and nodes are numbered from 0 in file order. Blank lines are skipped too,
//! and a last line without its newline is read (`log2graph` drops it).

use super::scan_graph::ScanNode;
use crate::geometry::{Point3, Pose};
use std::io::BufRead;

/// The longest line read: a point or a pose in any notation is far
/// shorter, and a file of one endless line is not held in memory.
pub const MAX_LINE_BYTES: usize = 4096;

/// The nodes of the log `reader` holds; an error names the line (1-based)
/// and what is wrong with it.
pub fn parse_scan_log(mut reader: impl BufRead) -> Result<Vec<ScanNode>, String> {
    let mut nodes: Vec<ScanNode> = Vec::new();
    let mut bytes = Vec::new();
    for number in 1.. {
        bytes.clear();
        let limit = MAX_LINE_BYTES as u64 + 1;
        let read = std::io::Read::take(&mut reader, limit)
            .read_until(b'\n', &mut bytes)
            .map_err(|e| format!("line {number}: {e}"))?;
        if read == 0 {
            break;
        }
        if bytes.len() > MAX_LINE_BYTES {
            return Err(format!(
                "line {number}: longer than {MAX_LINE_BYTES} bytes: not a line of a scan log"
            ));
        }
        let line = std::str::from_utf8(&bytes)
            .map_err(|_| format!("line {number}: not text (invalid UTF-8)"))?
            .trim_end_matches(['\n', '\r']);
        if line.starts_with('#') || line.starts_with(' ') || line.trim().is_empty() {
            continue;
        }
        let at = |what: String| format!("line {number}: {what}");
        let mut tokens = line.split_whitespace().peekable();
        if tokens.next_if_eq(&"NODE").is_some() {
            let [x, y, z, roll, pitch, yaw] = numbers(tokens).map_err(|e| {
                at(format!(
                    "{e} in `NODE x y z roll pitch yaw`, found '{}'",
                    shown(line)
                ))
            })?;
            let id = u32::try_from(nodes.len()).map_err(|_| at("too many nodes".into()))?;
            nodes.push(ScanNode {
                pixels: None,
                id,
                map_from_sensor: Pose::new([x, y, z], [roll, pitch, yaw]).to_isometry(),
                points: Vec::new(),
            });
        } else {
            let [x, y, z] = numbers(tokens).map_err(|e| {
                at(format!(
                    "{e} in a point `x y z` (or a `NODE x y z roll pitch yaw` line), found '{}'",
                    shown(line)
                ))
            })?;
            let node = nodes.last_mut().ok_or_else(|| {
                at("a point before the first `NODE x y z roll pitch yaw` line".into())
            })?;
            node.points.push(Point3::new(x, y, z));
        }
    }
    if nodes.is_empty() {
        return Err(
            "no `NODE x y z roll pitch yaw` line: neither a scan log nor a ScanGraph".into(),
        );
    }
    Ok(nodes)
}

/// The log of `nodes`: each node's pose as `NODE x y z roll pitch yaw`
/// ([`Pose::from_isometry`]), then its points; every number in the shortest
/// form that reads back to the same `f64`, so the points come back to the
/// bit and the poses to the rounding of their angles.
pub fn to_scan_log(nodes: &[ScanNode]) -> String {
    use std::fmt::Write as _;
    let mut text = String::from("# NODE x y z roll pitch yaw (m, rad), then x y z per point\n");
    for node in nodes {
        let pose = Pose::from_isometry(&node.map_from_sensor);
        let (t, r) = (pose.xyz, pose.rpy);
        let _ = writeln!(text, "NODE {} {} {} {} {} {}", t.x, t.y, t.z, r.x, r.y, r.z);
        for p in &node.points {
            let _ = writeln!(text, "{} {} {}", p.x, p.y, p.z);
        }
    }
    text
}

/// Exactly `N` finite numbers from `tokens`.
fn numbers<'a, const N: usize>(
    mut tokens: impl Iterator<Item = &'a str>,
) -> Result<[f64; N], String> {
    let mut values = [0.0; N];
    for (i, value) in values.iter_mut().enumerate() {
        let token = tokens
            .next()
            .ok_or_else(|| format!("{i} numbers where {N} belong"))?;
        *value = token
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("'{}' is not a finite number", shown(token)))?;
    }
    match tokens.count() {
        0 => Ok(values),
        more => Err(format!("{} numbers where {N} belong", N + more)),
    }
}

/// `text` trimmed, cut to 60 characters for an error message.
pub(super) fn shown(text: &str) -> String {
    let text = text.trim();
    match text.char_indices().nth(60) {
        Some((cut, _)) => format!("{}…", &text[..cut]),
        None => text.to_string(),
    }
}

#[cfg(test)]
mod tests;
