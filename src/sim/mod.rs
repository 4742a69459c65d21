//! The simulated workcell: scenes of meshes and primitives (parry3d), robots
//! from URDF, the laser range scanner, error profiles and the truth draw.
//!
//! parry's own vector and pose types stay inside this module; the rest of
//! sigmap speaks nalgebra.

pub mod ik;
pub mod mesh;
pub mod profile;
pub mod robot;
pub mod scan;
pub mod scene;
pub mod sensor;
pub mod streams;
pub mod truth;
