//! ROS 2 adapters (ros2-client, pure Rust) over the `constraint_dynamics` core.
//!
//! The core knows nothing of ROS; this crate holds the glue:
//! - [`msg`]: the ROS message and service types as serde structs,
//! - [`ros_args`]: `--ros-args` and ROS parameter-file parsing,
//! - [`ros_context`]: a ros2-client `Context` honouring `ROS_DOMAIN_ID` and a
//!   configurable set of network interfaces, and nodes whose spinner runs on a
//!   background thread.
//!
//! Every process that opens a DDS participant in tests must run inside a
//! loopback-only network namespace (`tools/ros2/netns_run.sh`).

pub mod msg;
pub mod ros_args;
pub mod ros_context;
