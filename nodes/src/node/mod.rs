//! What every node kind is made of: its logic behind [`worker::NodeLogic`], run on its own
//! thread by a [`worker::WorkerHandle`], and its ROS side behind [`wiring::RosWiring`], started
//! by [`start::start_node`] under its lifecycle ([`managed`]). The kinds (`crate::predictor`, …)
//! implement both traits.

mod failure;
pub mod health;
mod lifecycle_servers;
pub mod managed;
pub mod start;
pub mod state_readers;
mod timer;
pub mod wiring;
pub mod worker;
