//! The simulated workcell: what the robot really does and what its sensor
//! really returns.
//!
//! Owns the scene ([`scene`]: primitives and meshes in parry3d with a BVH for
//! ray casting; [`mesh`] readers), robots from URDF ([`robot`], inverse
//! kinematics in [`ik`]), the laser range scanner ([`sensor`]), the error
//! profiles ([`profile`]), the truth draw ([`truth`]), beam casting
//! ([`scan`]: a [`Scan`](crate::mapping::Scan) is what a mapper may see, a
//! [`scan::ScanTruth`] what only scoring may) and the counter-based random
//! streams ([`streams`]: one per run and per viewpoint, so results do not
//! depend on threads).
//!
//! parry's own vector and pose types stay inside this module; the rest of
//! sigmap speaks nalgebra.

pub mod believed;
pub mod ik;
pub mod mesh;
pub mod profile;
pub mod robot;
pub mod scan;
pub mod scene;
pub mod sensor;
pub mod streams;
pub mod truth;
