//! ROS 2 nodes (ros2-client, pure Rust) over the `constraint_dynamics` core.
//!
//! The core knows nothing of ROS; this crate holds the glue, layered so that only
//! [`suite`] owns ROS handles:
//! - [`msg`]: the ROS message and service types as serde structs,
//! - [`ros_args`]: `--ros-args` and ROS parameter-file parsing; [`params`]: the nodes' typed
//!   parameters,
//! - [`ros_context`]: a ros2-client `Context` honouring `ROS_DOMAIN_ID` and a configurable set
//!   of network interfaces, and nodes whose spinner runs on a background thread,
//! - [`state`], [`convert`], [`engine`]: the domain side (latest state, message ↔ core
//!   conversions, what each request and prediction computes) — plain data in and out,
//! - [`worker`]: one thread per node that owns its engine and handles domain events off the
//!   executor,
//! - [`suite`]: starts the nodes, translates messages and requests into events, publishes,
//! - [`logging`]: stderr and `/rosout`.
//!
//! Every process that opens a DDS participant in tests must run inside a loopback-only
//! network namespace (`tools/ros2/netns_run.sh`). See `docs/nodes.md`.

pub mod convert;
pub mod engine;
pub mod logging;
pub mod msg;
pub mod params;
pub mod ros_args;
pub mod ros_context;
pub mod state;
pub mod suite;
pub mod worker;
