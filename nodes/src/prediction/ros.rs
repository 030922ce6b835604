//! `cd_prediction` on ROS: the `~/predict` server.

use super::{PredictionInput, PredictionNode};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::srv::{Predict, PredictResponse};
use crate::node::wiring::{RosWiring, Wiring};
use crate::node::worker::Event;
use crate::ros::io::serve;

impl RosWiring for PredictionNode {
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError> {
        let server = w.ros.server::<Predict>(&(w.topic)("~/predict"))?;
        let tx = w.tx.clone();
        w.tasks.push(w.ros.spawn(serve::<Predict, _>(
            server,
            w.log.clone(),
            move |req, reply| {
                tx.try_send(Event::Node(PredictionInput::Predict(req, reply)))
                    .is_ok()
            },
            |message| PredictResponse {
                success: false,
                message,
                ..Default::default()
            },
        )));
        Ok(())
    }
}
