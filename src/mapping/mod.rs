//! Occupancy modelling: the probabilistic octree, its OctoMap files, and the
//! two ways of filling it (the paper's OPDF merge and OctoMap's ray update).

pub mod chord;
pub mod merge;
pub mod octomap_io;
pub mod octree;
pub mod opdf;
pub mod pooling;
pub mod ray_update;
pub mod settings;
pub mod shared_motion;
pub mod spherical;
pub mod viewpoint;

pub use octree::{Clamp, Key, Leaf, Octree, TreeStats};
pub use settings::MapSettings;
