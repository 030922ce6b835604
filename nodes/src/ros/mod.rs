//! ROS 2 plumbing, knowing nothing of the physics: the command line and parameter files
//! ([`args`]), the DDS context and nodes ([`context`]), the network rule
//! ([`network_guard`]), logging to stderr and `/rosout` ([`logging`]), the executor loops
//! that feed subscriptions and services to a worker ([`io`]), and returning freed heap to the
//! OS ([`heap`]).

pub mod args;
pub mod context;
pub mod heap;
pub mod io;
pub mod logging;
pub mod network_guard;
