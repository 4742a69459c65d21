//! OctoMap's ScanGraph files (`.graph`): scans with their poses, as
//! `graph2tree`, `octovis` and `ScanGraph::readBinary` read them
//! (docs/octomap.md, "ScanGraph files"). Little-endian:
//!
//! ```text
//! graph      := u32 n | node × n | u32 m | edge × m
//! node       := pointcloud | pose6d | u32 id      (points in the sensor frame)
//! pointcloud := u32 count | vector3 × count
//! pose6d     := vector3 (translation) | quaternion
//! vector3    := i32 3 | f64 x | f64 y | f64 z
//! quaternion := i32 4 | f64 w | f64 x | f64 y | f64 z
//! edge       := u32 first | u32 second | pose6d constraint | f64 weight
//! ```
//!
//! sigmap writes no edges and reads past them.

use super::scan::PixelRaster;
use crate::geometry::{Isometry3, Point3, Vector3};
use nalgebra::{Quaternion, Translation3, UnitQuaternion};

/// One scan of a graph: the pose of its sensor frame (`map_from_sensor`)
/// and its points in the sensor frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanNode {
    /// The node's id.
    pub id: u32,
    /// Maps sensor coordinates to map coordinates.
    pub map_from_sensor: Isometry3,
    /// End points in the sensor frame (OctoMap keeps them as `f32`).
    pub points: Vec<Point3>,
    /// The pixel of each point, where the points came from an image (a
    /// graph or a log does not carry them).
    pub pixels: Option<PixelRaster>,
}

/// Bytes of one point (`i32` tag and three `f64`).
const POINT_BYTES: usize = 4 + 3 * 8;
/// Bytes of one pose (translation and quaternion).
const POSE_BYTES: usize = POINT_BYTES + 4 + 4 * 8;

fn put_vector(out: &mut Vec<u8>, v: [f64; 3]) {
    out.extend_from_slice(&3i32.to_le_bytes());
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// The `.graph` bytes of `nodes` (no edges).
pub fn to_scan_graph(nodes: &[ScanNode]) -> Vec<u8> {
    let points: usize = nodes.iter().map(|n| n.points.len()).sum();
    let mut out = Vec::with_capacity(8 + nodes.len() * (8 + POSE_BYTES) + points * POINT_BYTES);
    out.extend_from_slice(&(nodes.len() as u32).to_le_bytes());
    for node in nodes {
        out.extend_from_slice(&(node.points.len() as u32).to_le_bytes());
        for p in &node.points {
            put_vector(&mut out, [p.x, p.y, p.z]);
        }
        let t = node.map_from_sensor.translation.vector;
        put_vector(&mut out, [t.x, t.y, t.z]);
        let q = node.map_from_sensor.rotation.quaternion();
        out.extend_from_slice(&4i32.to_le_bytes());
        for x in [q.w, q.i, q.j, q.k] {
            out.extend_from_slice(&x.to_le_bytes());
        }
        out.extend_from_slice(&node.id.to_le_bytes());
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    out
}

/// A cursor over the bytes that says what is wrong and where.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        let end = self.at + N;
        let slice = self.bytes.get(self.at..end).ok_or_else(|| {
            format!(
                "truncated: {what} at byte {} runs past the end ({} bytes)",
                self.at,
                self.bytes.len()
            )
        })?;
        self.at = end;
        Ok(slice.try_into().expect("N bytes"))
    }

    fn u32(&mut self, what: &str) -> Result<u32, String> {
        self.take::<4>(what).map(u32::from_le_bytes)
    }

    fn f64(&mut self, what: &str) -> Result<f64, String> {
        let v = f64::from_le_bytes(self.take::<8>(what)?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{what} at byte {} is {v}", self.at - 8))
        }
    }

    fn tagged<const N: usize>(&mut self, what: &str) -> Result<[f64; N], String> {
        let tag = i32::from_le_bytes(self.take::<4>(what)?);
        if tag != N as i32 {
            return Err(format!(
                "{what} at byte {} has size tag {tag}, not {N}: not a ScanGraph file?",
                self.at - 4
            ));
        }
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(what)?;
        }
        Ok(out)
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }
}

/// Reads a `.graph` file's nodes (edges are skipped). Errors say what is
/// wrong: truncation, counts larger than the file, NaN or infinite values,
/// a quaternion far from unit length.
pub fn parse_scan_graph(bytes: &[u8]) -> Result<Vec<ScanNode>, String> {
    let mut r = Reader { bytes, at: 0 };
    let n = r.u32("the node count")? as usize;
    if n.saturating_mul(4 + POSE_BYTES + 4) > r.remaining() {
        return Err(format!(
            "{n} nodes cannot fit in {} bytes: not a ScanGraph file, or truncated",
            bytes.len()
        ));
    }
    let mut nodes = Vec::with_capacity(n);
    for k in 0..n {
        let count = r.u32("a point count")? as usize;
        if count.saturating_mul(POINT_BYTES) > r.remaining() {
            return Err(format!(
                "node {k} claims {count} points, more than the {} bytes left hold",
                r.remaining()
            ));
        }
        let mut points = Vec::with_capacity(count);
        for _ in 0..count {
            let [x, y, z] = r.tagged::<3>("a point")?;
            points.push(Point3::new(x, y, z));
        }
        let [x, y, z] = r.tagged::<3>("a pose translation")?;
        let [w, i, j, l] = r.tagged::<4>("a pose rotation")?;
        let q = Quaternion::new(w, i, j, l);
        if (q.norm() - 1.0).abs() > 1e-3 {
            return Err(format!(
                "node {k}: the pose quaternion has norm {}, not 1",
                q.norm()
            ));
        }
        let id = r.u32("a node id")?;
        nodes.push(ScanNode {
            pixels: None,
            id,
            map_from_sensor: Isometry3::from_parts(
                Translation3::from(Vector3::new(x, y, z)),
                UnitQuaternion::from_quaternion(q),
            ),
            points,
        });
    }
    r.u32("the edge count")?;
    Ok(nodes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nodes() -> Vec<ScanNode> {
        (0..3)
            .map(|k| ScanNode {
                pixels: None,
                id: k,
                map_from_sensor: Isometry3::new(
                    Vector3::new(0.1 * k as f64, -0.2, 0.5),
                    Vector3::new(0.3, -0.1 * k as f64, 1.2),
                ),
                points: (0..5)
                    .map(|i| Point3::new(i as f64 * 0.25, -0.5, 1.0 + k as f64))
                    .collect(),
            })
            .collect()
    }

    #[test]
    fn graphs_round_trip_and_have_octomaps_layout() {
        let nodes = nodes();
        let bytes = to_scan_graph(&nodes);
        // n, per node (count, points, pose, id), m.
        assert_eq!(bytes.len(), 4 + 3 * (4 + 5 * 28 + 28 + 36 + 4) + 4);
        assert_eq!(&bytes[..4], &3u32.to_le_bytes());
        assert_eq!(&bytes[4..8], &5u32.to_le_bytes());
        assert_eq!(&bytes[8..12], &3i32.to_le_bytes());
        let back = parse_scan_graph(&bytes).unwrap();
        assert_eq!(back.len(), 3);
        for (a, b) in back.iter().zip(&nodes) {
            assert_eq!(a.id, b.id);
            assert_eq!(a.points, b.points);
            let p = Point3::new(0.3, 0.2, 0.1);
            assert!((a.map_from_sensor * p - b.map_from_sensor * p).norm() < 1e-12);
        }
    }

    #[test]
    fn bad_graphs_say_what_is_wrong() {
        let bytes = to_scan_graph(&nodes());
        let err = |b: &[u8]| parse_scan_graph(b).unwrap_err();
        assert!(err(&bytes[..bytes.len() - 3]).contains("truncated"));
        assert!(err(&bytes[..100]).contains("truncated") || err(&bytes[..100]).contains("claims"));
        let mut huge = bytes.clone();
        huge[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(err(&huge).contains("claims"), "{}", err(&huge));
        let mut many = bytes.clone();
        many[..4].copy_from_slice(&1_000_000u32.to_le_bytes());
        assert!(err(&many).contains("cannot fit"));
        let mut nan = bytes.clone();
        nan[12..20].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(err(&nan).contains("NaN"), "{}", err(&nan));
        let mut tag = bytes.clone();
        tag[8..12].copy_from_slice(&7i32.to_le_bytes());
        assert!(err(&tag).contains("size tag 7"));
        assert!(err(b"").contains("node count"));
    }
}
