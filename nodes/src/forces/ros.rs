//! `cd_forces` on ROS: the `~/get_constraint_forces` server.

use super::{ForcesInput, ForcesNode};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::srv::{GetConstraintForces, GetConstraintForcesResponse};
use crate::node::wiring::{RosWiring, Wiring, serve_service};

impl RosWiring for ForcesNode {
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError> {
        serve_service::<_, GetConstraintForces>(
            w,
            "~/get_constraint_forces",
            ForcesInput::Get,
            |message| GetConstraintForcesResponse {
                success: false,
                message,
                ..Default::default()
            },
        )
    }
}
