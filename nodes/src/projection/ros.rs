//! `cd_projection` on ROS: the `~/project_velocity` server and the command filter's topics.

use super::{Filtered, ProjectionInput, ProjectionNode};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::srv::{ProjectVelocity, ProjectVelocityResponse};
use crate::msg::geometry_msgs::{Twist, TwistStamped};
use crate::node::wiring::{RosWiring, Wiring, forward, serve_service};
use crate::node::worker::Event;
use crate::ros::context::qos;
use crate::ros::io::subscribe;

impl RosWiring for ProjectionNode {
    fn wire(w: &mut Wiring<Self>) -> Result<(), NodeError> {
        let p = &w.params.node;
        if p.service {
            serve_service::<_, ProjectVelocity>(
                w,
                "~/project_velocity",
                |req, reply| ProjectionInput::Project(Box::new(req), reply),
                |message| ProjectVelocityResponse {
                    success: false,
                    status: "error".into(),
                    message,
                    ..Default::default()
                },
            )?;
        }
        let p = &w.params.node;
        if !p.filter.enabled {
            return Ok(());
        }
        let (input, output) = (
            (w.topic)(&p.filter.input_topic),
            (w.topic)(&p.filter.output_topic),
        );
        let tx = w.tx.clone();
        let log = w.log.clone();
        let Some(out_rx) = w.outputs.take() else {
            return Ok(());
        };
        if p.filter.stamped {
            let sub = w
                .ros
                .subscription::<TwistStamped>(&input, &qos::sensor_data())?;
            w.tasks.push(
                w.ros
                    .spawn(subscribe(sub, w.log.clone(), move |m: TwistStamped| {
                        forward(
                            &tx,
                            Event::Node(ProjectionInput::Filter(m.twist, Some(m.header))),
                        )
                    })),
            );
            let publisher = w
                .ros
                .publisher::<TwistStamped>(&output, &qos::reliable(10))?;
            w.tasks.push(w.ros.spawn(async move {
                while let Ok(Filtered(twist, header)) = out_rx.recv().await {
                    let msg = TwistStamped {
                        header: header.unwrap_or_default(),
                        twist,
                    };
                    if let Err(e) = publisher.async_publish(msg).await {
                        log.warn(&format!("publish filtered command: {e:?}"));
                    }
                }
            }));
        } else {
            let sub = w.ros.subscription::<Twist>(&input, &qos::sensor_data())?;
            w.tasks
                .push(w.ros.spawn(subscribe(sub, w.log.clone(), move |m: Twist| {
                    forward(&tx, Event::Node(ProjectionInput::Filter(m, None)))
                })));
            let publisher = w.ros.publisher::<Twist>(&output, &qos::reliable(10))?;
            w.tasks.push(w.ros.spawn(async move {
                while let Ok(Filtered(twist, _)) = out_rx.recv().await {
                    if let Err(e) = publisher.async_publish(twist).await {
                        log.warn(&format!("publish filtered command: {e:?}"));
                    }
                }
            }));
        }
        Ok(())
    }
}
