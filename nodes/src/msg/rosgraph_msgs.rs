//! `rosgraph_msgs/msg/*`.

use serde::{Deserialize, Serialize};

use super::builtin_interfaces::Time;

/// `rosgraph_msgs/msg/Clock`: simulated time on `/clock` (read when `use_sim_time`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Clock {
    pub clock: Time,
}

super::ros_messages!("rosgraph_msgs": Clock);
