//! `cd_prediction` on ROS: the `~/predict` and `~/rollouts` servers.

use super::{PredictionInput, PredictionNode};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::srv::{
    Predict, PredictResponse, Rollouts, RolloutsResponse,
};
use crate::node::wiring::{RosWiring, Wiring, serve_service};

impl RosWiring for PredictionNode {
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError> {
        serve_service::<_, Predict>(w, "~/predict", PredictionInput::Predict, |message| {
            PredictResponse {
                success: false,
                message,
                ..Default::default()
            }
        })?;
        serve_service::<_, Rollouts>(w, "~/rollouts", PredictionInput::Rollouts, |message| {
            RolloutsResponse {
                success: false,
                message,
                ..Default::default()
            }
        })
    }
}
