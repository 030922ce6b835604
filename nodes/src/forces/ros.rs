//! `cd_forces` on ROS: the `~/get_constraint_forces` server.

use super::{ForcesInput, ForcesNode};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::srv::{GetConstraintForces, GetConstraintForcesResponse};
use crate::node::wiring::{RosWiring, Wiring};
use crate::node::worker::Event;
use crate::ros::io::serve;

impl RosWiring for ForcesNode {
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError> {
        let server = w
            .ros
            .server::<GetConstraintForces>(&(w.topic)("~/get_constraint_forces"))?;
        let tx = w.tx.clone();
        w.tasks.push(w.ros.spawn(serve::<GetConstraintForces, _>(
            server,
            w.log.clone(),
            move |req, reply| {
                tx.try_send(Event::Node(ForcesInput::Get(req, reply)))
                    .is_ok()
            },
            |message| GetConstraintForcesResponse {
                success: false,
                message,
                ..Default::default()
            },
        )));
        Ok(())
    }
}
