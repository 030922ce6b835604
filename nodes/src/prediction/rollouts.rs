//! `~/rollouts`: N command sequences from one start state, N predicted trajectories, on all the
//! node's cores (`Predictor::rollouts`) — what a sampling planner (Nav2 MPPI) scores.

use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{IntegrationOverrides, PredictionRequest, RolloutOptions};

use super::PredictionNode;
use crate::convert::{ForcesAt, pose_msg, time_plus, twist_msg};
use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::srv::{RolloutsRequest, RolloutsResponse};
use crate::msg::std_msgs::Header;

impl PredictionNode {
    /// `~/rollouts`: a refused request is `success = false` with the reason.
    pub fn rollouts(&mut self, req: &RolloutsRequest, now: Time) -> RolloutsResponse {
        self.try_rollouts(req, now)
            .unwrap_or_else(|e| RolloutsResponse {
                success: false,
                message: e.to_string(),
                ..Default::default()
            })
    }

    /// The number of sequences, after checking the request's size against the node's limits.
    fn check_rollouts(&self, req: &RolloutsRequest) -> Result<usize, NodeError> {
        let p = &self.params.node;
        let len = req.sequence_length as usize;
        if !(req.step.is_finite() && req.step > 0.0) {
            return Err(NodeError::request(
                "step",
                format!("{} s must be positive and finite", req.step),
            ));
        }
        if len == 0 || req.commands.is_empty() || !req.commands.len().is_multiple_of(len) {
            return Err(NodeError::request(
                "commands",
                format!(
                    "{} commands are not N ≥ 1 sequences of sequence_length = {len}",
                    req.commands.len()
                ),
            ));
        }
        let n = req.commands.len() / len;
        if n > p.max_rollouts as usize {
            return Err(NodeError::request(
                "commands",
                format!("{n} sequences: at most max_rollouts = {}", p.max_rollouts),
            ));
        }
        if req.commands.len() > p.max_rollout_samples as usize {
            return Err(NodeError::request(
                "commands",
                format!(
                    "{n} sequences × {len} steps = {} samples: at most max_rollout_samples = {}",
                    req.commands.len(),
                    p.max_rollout_samples
                ),
            ));
        }
        let horizon = len as f64 * req.step;
        if horizon > p.max_horizon {
            return Err(NodeError::request(
                "step",
                format!(
                    "sequence_length {len} × step {} s = {horizon} s is longer than max_horizon = \
                     {} s",
                    req.step, p.max_horizon
                ),
            ));
        }
        Ok(n)
    }

    fn try_rollouts(
        &mut self,
        req: &RolloutsRequest,
        now: Time,
    ) -> Result<RolloutsResponse, NodeError> {
        let n = self.check_rollouts(req)?;
        let len = req.sequence_length as usize;
        let common = &self.params.common;
        let (q, v) =
            self.robot
                .request_state(common, req.use_latest_state, (&[], &req.q), (&[], &req.v))?;
        let hold = self.params.node.command.hold_joints;
        let mut sequences: Vec<Vec<Command>> = Vec::with_capacity(n);
        for (j, chunk) in req.commands.chunks(len).enumerate() {
            let mut seq = Vec::with_capacity(len);
            for (i, t) in chunk.iter().enumerate() {
                let base = self
                    .robot
                    .twist_command(t, &format!("commands[{}]", j * len + i))?;
                seq.push(self.robot.command(Some(base), &q, hold));
            }
            sequences.push(seq);
        }
        let opts = RolloutOptions {
            step: req.step,
            threads: self.params.node.rollout_threads as usize,
        };
        // A planner's rollouts: no error-estimate companion (it doubles the work and the reply
        // has no place for it) and no covariance; the node's own predictions keep both.
        let request = PredictionRequest {
            integration: IntegrationOverrides {
                error_estimate: Some(false),
                adapt: Some(false),
                ..IntegrationOverrides::default()
            },
            forces: req.with_forces,
            contact_limits: self.robot.contact_limits(common),
            lagged_command: super::lag_start(self.rollout_predictor.config().actuators(), &v),
            ..PredictionRequest::new(&q, &v)
        };
        let trajectories = self
            .rollout_predictor
            .rollouts(&request, &sequences, opts)
            .map_err(NodeError::core("rollouts"))?;
        let model = self.robot.model();
        let mut reply = RolloutsResponse {
            success: true,
            header: Header {
                stamp: now,
                frame_id: common.frames.odom_frame.clone(),
            },
            poses: Vec::with_capacity(n * len),
            twists: Vec::with_capacity(n * len),
            ..Default::default()
        };
        let mut steps = 0;
        for traj in &trajectories {
            steps += traj.steps;
            // Sample 0 is the common start state: the reply has the samples after each step.
            for s in traj.samples.iter().skip(1) {
                reply.poses.push(pose_msg(&model.base_pose(&s.q)));
                reply.twists.push(twist_msg(&model.base_twist(&s.v)));
                if let Some(at) = ForcesAt::of_sample(s) {
                    let stamp = time_plus(now, s.t);
                    reply.forces.push(self.robot.forces_msg(common, &at, stamp));
                }
            }
        }
        if reply.poses.len() != n * len {
            return Err(NodeError::request(
                "step",
                format!(
                    "the rollouts have {} samples, not {n} × {len}: step is below the scene's \
                     sampling resolution",
                    reply.poses.len()
                ),
            ));
        }
        reply.message = format!(
            "{n} rollouts × {len} steps of {} s, {steps} integration steps",
            req.step
        );
        Ok(reply)
    }
}
