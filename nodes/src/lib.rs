//! ROS 2 nodes (ros2-client, pure Rust) over the `constraint_dynamics` core.
//!
//! The core knows nothing of ROS; this crate holds the glue, in three layers:
//! - the ROS plumbing, knowing nothing of the physics: [`ros`] (command line and parameter
//!   files, DDS context and nodes, the network rule, logging, executor loops) and [`msg`] (the
//!   message and service types as serde structs);
//! - the domain side, plain data in and out: [`params`] (typed parameters shared by every
//!   kind), [`robot`] (the scene a node serves and its latest state), [`convert`] (core values
//!   ↔ messages), and one module per node kind — [`predictor`], [`forces`], [`projection`],
//!   [`prediction`] — each with its logic (`mod.rs`), its own parameters and its ROS wiring
//!   (`ros.rs`);
//! - [`node`]: what every kind is made of — its logic on a worker thread, its ROS wiring;
//! - [`suite`]: starts the enabled nodes on one participant, and the binaries' `main`.
//!
//! Every process that opens a DDS participant in tests must run inside a loopback-only
//! network namespace (`tools/ros2/netns_run.sh`). See `docs/nodes.md`.

#![warn(missing_docs)]

pub mod bag;
pub mod convert;
pub mod covariance;
pub mod error;
pub mod forces;
pub mod lifecycle;
// The message structs mirror the .msg/.srv files field by field; their documentation is in
// `interfaces/constraint_dynamics_msgs/` and the ROS 2 interface packages.
#[allow(missing_docs)]
pub mod msg;
pub mod node;
pub mod params;
pub mod prediction;
pub mod predictor;
pub mod projection;
pub mod robot;
pub mod ros;
pub mod suite;

pub use error::NodeError;
