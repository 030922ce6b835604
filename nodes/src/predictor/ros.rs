//! `cd_predictor` on ROS: the command subscription and the three publishers.

use super::{PredictorInput, PredictorNode};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::ConstraintForces;
use crate::msg::geometry_msgs::{Twist, TwistStamped};
use crate::msg::nav_msgs::{Odometry, Path};
use crate::node::wiring::{RosWiring, Wiring, forward};
use crate::node::worker::Event;
use crate::ros::context::qos;
use crate::ros::io::subscribe;

impl RosWiring for PredictorNode {
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError> {
        let p = &w.params.node;
        let cmd_topic = (w.topic)(&p.command.topic);
        let tx = w.tx.clone();
        if p.command.stamped {
            let sub = w
                .ros
                .subscription::<TwistStamped>(&cmd_topic, &qos::sensor_data())?;
            w.tasks.push(
                w.ros
                    .spawn(subscribe(sub, w.log.clone(), move |m: TwistStamped| {
                        forward(&tx, Event::Node(PredictorInput::Command(m.twist)))
                    })),
            );
        } else {
            let sub = w
                .ros
                .subscription::<Twist>(&cmd_topic, &qos::sensor_data())?;
            w.tasks
                .push(w.ros.spawn(subscribe(sub, w.log.clone(), move |m: Twist| {
                    forward(&tx, Event::Node(PredictorInput::Command(m)))
                })));
        }
        let odom_pub = w
            .ros
            .publisher::<Odometry>(&(w.topic)("~/predicted_odom"), &qos::reliable(10))?;
        let path_pub = match p.publish_path {
            true => Some(
                w.ros
                    .publisher::<Path>(&(w.topic)("~/predicted_path"), &qos::reliable(10))?,
            ),
            false => None,
        };
        let forces_pub = match p.publish_forces {
            true => Some(w.ros.publisher::<ConstraintForces>(
                &(w.topic)("~/constraint_forces"),
                &qos::reliable(10),
            )?),
            false => None,
        };
        let log = w.log.clone();
        let Some(out_rx) = w.outputs.take() else {
            return Ok(());
        };
        w.tasks.push(w.ros.spawn(async move {
            while let Ok(out) = out_rx.recv().await {
                let out = *out;
                if let Err(e) = odom_pub.async_publish(out.odom).await {
                    log.warn(&format!("publish predicted_odom: {e:?}"));
                }
                if let Some(p) = &path_pub
                    && let Err(e) = p.async_publish(out.path).await
                {
                    log.warn(&format!("publish predicted_path: {e:?}"));
                }
                if let Some(p) = &forces_pub
                    && let Err(e) = p.async_publish(out.forces).await
                {
                    log.warn(&format!("publish constraint_forces: {e:?}"));
                }
            }
        }));
        Ok(())
    }
}
