//! `constraint_dynamics`: constrained rigid-body dynamics from URDF.
//!
//! Layers, each a folder: [`spatial`] (6D algebra), [`model`] (URDF → bodies, joints, frames,
//! coordinates), [`algorithm`] (kinematics, Jacobians, RNEA, CRBA, ABA, energies), [`scene`] (the
//! YAML scene file). The crate knows nothing of ROS; the nodes in `nodes/` adapt it.
//!
//! Dynamics convention: `M(q) q̈ + h(q, v) = τ + Jᵀλ`, SI units, gravity in world axes.

// Featherstone's recurrences read best as index loops over bodies and coordinates.
#![allow(clippy::needless_range_loop)]
#![warn(missing_docs)]

pub mod actuators;
pub mod algorithm;
pub mod applied;
pub mod calibrate;
pub mod constraints;
pub mod derivatives;
pub mod dynamics;
pub mod envelope;
pub mod error;
pub mod forces;
pub mod limits;
pub mod linalg;
pub mod model;
pub mod monitor;
pub mod predict;
pub mod projection;
pub mod replay;
pub mod robot_limits;
pub mod scene;
mod scene_errors;
pub mod spatial;
pub mod system;
#[cfg(test)]
mod test_rng;

pub use error::{Error, Result};
pub use model::{BaseType, Model, ModelOptions};
pub use scene::Scene;
pub use system::System;
