//! What every node kind is made of: its logic behind [`worker::NodeLogic`], run on its own
//! thread by a [`worker::WorkerHandle`], and its ROS side behind [`wiring::RosWiring`], started
//! by [`start::start_node`] under its lifecycle ([`managed`]). The kinds (`crate::predictor`, …)
//! implement both traits.

mod failure;
pub mod health;
pub mod managed;
pub mod start;
mod timer;
pub mod wiring;
pub mod worker;
