//! How a worker applies its state inputs: what its inbox collected since it last ran, oldest
//! first, each stamped with its arrival (wall clock; under `use_sim_time` the worker's clock
//! when it takes it, as the inbox wakes it per message then). Every message is applied, so
//! what the kind does per message (the predictor's residual monitor and controller integrals)
//! sees each one, in order; health and the state's input times record the arrivals.

use std::time::Instant;

use super::{NodeLogic, StateMsg, Worker};
use crate::msg::builtin_interfaces::Time;
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;
use crate::node::health::Input;

impl<N: NodeLogic> Worker<N> {
    /// Applies what the inbox holds. A panic while applying one message is caught like an
    /// event's (the logic is rebuilt) and the messages after it are still applied.
    pub(super) fn take_state(&mut self) {
        self.inbox.take(&mut self.taken);
        while !self.taken.is_empty() {
            self.guarded("state input", |w| {
                let sim = w.logic.params().common.use_sim_time;
                while let Some((arrived, msg)) = w.taken.pop_front() {
                    let at = if sim { w.now() } else { arrived };
                    match msg {
                        StateMsg::JointState(js) => w.joint_state(&js, at),
                        StateMsg::Odometry(od) => w.odometry(&od, at),
                    }
                }
                false
            });
        }
    }

    fn joint_state(&mut self, js: &JointState, at: Time) {
        match self.logic.robot_mut().state_mut().apply_joint_state(js) {
            Ok(report) => {
                self.health.input(Input::JointStates, at);
                self.logic.robot_mut().state_mut().joint_states_at = Some(at);
                self.logic.joint_state_applied(js);
                if !report.unknown.is_empty() && !self.warned.unknown_joints {
                    self.warned.unknown_joints = true;
                    self.log.info(&format!(
                        "joint_states: ignoring joints the model does not have: {}",
                        report.unknown.join(", ")
                    ));
                }
            }
            Err(e) => {
                let e = e.to_string();
                let level = self.drops.level("joint_state", &e, Instant::now());
                self.log
                    .log(level, &format!("dropped a joint state message: {e}"));
            }
        }
    }

    fn odometry(&mut self, od: &Odometry, at: Time) {
        match self.logic.robot_mut().apply_odometry(od) {
            Ok(()) => {
                self.health.input(Input::Odometry, at);
                self.logic.robot_mut().state_mut().odom_at = Some(at);
                self.logic.odometry_applied(od);
            }
            Err(e) => {
                let e = e.to_string();
                let level = self.drops.level("odometry", &e, Instant::now());
                self.log
                    .log(level, &format!("dropped an odometry message: {e}"));
            }
        }
    }
}
