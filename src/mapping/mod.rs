//! Occupancy modelling: everything a mapper does, and nothing it may not know.
//!
//! Owns the probabilistic [`Octree`] (OctoMap's keys and log-odds, its `.bt`
//! and `.ot` files in [`octomap_io`]), the two ways of filling it — the
//! paper's OPDF merge (a viewpoint's local spherical grid, [`viewpoint`] and
//! [`spherical`], merged by [`merge`] with the cell model of [`chord`]; beam
//! [`pooling`]; the [`shared_motion`] step for correlated errors) and
//! OctoMap's ray update ([`ray_update`]) — and the [`MapSettings`] both are
//! built with — and the one map builder ([`build_map`]) that serves every
//! method for simulated and recorded [`Scan`]s alike. It never imports
//! `sim`, `eval` or `experiment`: the truth cannot reach it
//! (docs/architecture.md).
//!
//! ```
//! use sigmap::geometry::{Point3, Vector3};
//! use sigmap::mapping::ray_update::RayUpdater;
//! use sigmap::mapping::Octree;
//! let mut tree = Octree::new(0.05);
//! let origin = Point3::new(0.0, 0.0, 0.5);
//! let hits = [Point3::new(0.3, 0.0, 0.0)];
//! RayUpdater::default().insert_scan(&mut tree, &origin, &hits, &[-Vector3::z()], 2.0);
//! assert!(tree.value_at(&hits[0]).unwrap() > 0.0); // occupied
//! assert!(tree.value_at(&Point3::new(0.0, 0.0, 0.2)).unwrap() < 0.0); // free
//! ```

pub mod build;
pub mod chord;
pub mod cloud_grids;
pub mod depth_images;
pub mod measured;
pub mod merge;
pub mod method;
pub mod octomap_io;
pub mod octree;
pub mod opdf;
pub mod pipeline;
pub mod pooling;
pub mod ray_update;
pub mod scan;
pub mod scan_graph;
pub mod scan_log;
pub mod settings;
pub mod shared_motion;
pub mod spherical;
pub mod surface_cells;
pub mod viewpoint;

pub use build::{build_map, build_map_with, BuildExtras};
pub use method::Method;
pub use octree::{Clamp, Key, Leaf, Octree, TreeStats};
pub use scan::{BeamLayout, Layouts, MapperView, Scan};
pub use settings::MapSettings;
