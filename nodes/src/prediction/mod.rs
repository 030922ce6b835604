//! `cd_prediction`: a prediction on request (`~/predict`): from the latest state (or one the
//! request gives), under a sequence of base commands, over a horizon, with the constraint forces
//! at every sample if asked, and the propagated covariance at every sample if asked; and
//! rollouts for sampling planners (`~/rollouts`): N command sequences, N trajectories. A drive
//! that follows its commands late (`command_lag`) starts each from its wheels' speeds.

pub mod params;
mod rollouts;
pub mod ros;

use constraint_dynamics::actuators::Actuators;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use nalgebra::DMatrix;

use crate::convert::{ForcesAt, path_msg, time_plus};
use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::srv::{
    PredictRequest, PredictResponse, RolloutsRequest, RolloutsResponse,
};
use crate::node::worker::{NodeLogic, Reply};
use crate::params::NodeParams;
use crate::robot::Robot;
use crate::robot::inputs::{InputAges, StartCovariance};
use crate::ros::logging::NodeLog;
pub use params::PredictionParams;

/// What the prediction node reacts to.
pub enum PredictionInput {
    /// `~/predict`.
    Predict(PredictRequest, Reply<PredictResponse>),
    /// `~/rollouts`.
    Rollouts(RolloutsRequest, Reply<RolloutsResponse>),
}

/// The prediction node's logic: a robot and its predictors.
pub struct PredictionNode {
    robot: Robot,
    predictor: Predictor,
    /// `~/rollouts`': the scene's `rollouts:` settings where it has them (`Scene::rollout_scene`).
    rollout_predictor: Predictor,
    params: NodeParams<PredictionParams>,
    start_covariance: StartCovariance,
}

impl NodeLogic for PredictionNode {
    type Params = PredictionParams;
    type Input = PredictionInput;
    type Output = ();

    fn new(
        robot: Robot,
        params: NodeParams<PredictionParams>,
        _log: NodeLog,
    ) -> Result<Self, NodeError> {
        let predictor =
            Predictor::from_scene(robot.scene()).map_err(NodeError::core("predictor"))?;
        let rollout_predictor = Predictor::from_scene(&robot.scene().rollout_scene())
            .map_err(NodeError::core("rollouts predictor"))?;
        let start_covariance = StartCovariance::new(
            robot.model(),
            &params.common.state,
            &robot.scene().file.uncertainty,
        )?;
        Ok(PredictionNode {
            robot,
            predictor,
            rollout_predictor,
            params,
            start_covariance,
        })
    }
    fn robot(&self) -> &Robot {
        &self.robot
    }
    fn robot_mut(&mut self) -> &mut Robot {
        &mut self.robot
    }
    fn params(&self) -> &NodeParams<PredictionParams> {
        &self.params
    }
    fn set_params(&mut self, params: NodeParams<PredictionParams>) {
        self.params = params;
    }
    fn handle(&mut self, input: PredictionInput, now: Time, _out: &mut dyn FnMut(())) {
        match input {
            PredictionInput::Predict(req, reply) => {
                let _ = reply.try_send(self.predict(&req, now));
            }
            PredictionInput::Rollouts(req, reply) => {
                let _ = reply.try_send(self.rollouts(&req, now));
            }
        }
    }
}

impl PredictionNode {
    /// `~/predict`: a refused request is `success = false` with the reason.
    pub fn predict(&mut self, req: &PredictRequest, now: Time) -> PredictResponse {
        self.try_predict(req, now)
            .unwrap_or_else(|e| PredictResponse {
                success: false,
                message: e.to_string(),
                ..Default::default()
            })
    }

    /// Checks the request's size against the node's limits before any work.
    fn check_limits(&self, req: &PredictRequest) -> Result<(), NodeError> {
        let p = &self.params.node;
        if !(req.horizon.is_finite() && req.horizon > 0.0) {
            return Err(NodeError::request(
                "horizon",
                format!("{} s must be positive and finite", req.horizon),
            ));
        }
        if req.horizon > p.max_horizon {
            return Err(NodeError::request(
                "horizon",
                format!(
                    "{} s is longer than max_horizon = {} s",
                    req.horizon, p.max_horizon
                ),
            ));
        }
        if req.commands.len() > p.max_commands as usize {
            return Err(NodeError::request(
                "commands",
                format!(
                    "{}: at most max_commands = {}",
                    req.commands.len(),
                    p.max_commands
                ),
            ));
        }
        if req.commands.len() > 1 && !(req.command_period.is_finite() && req.command_period > 0.0) {
            return Err(NodeError::request(
                "command_period",
                format!(
                    "{} s must be positive with more than one command",
                    req.command_period
                ),
            ));
        }
        Ok(())
    }

    /// The request's start covariance (n × n row-major, n = 2nv), or the one the latest
    /// inputs give (odometry covariances, joint noise, process noise over their age).
    fn request_covariance(
        &self,
        req: &PredictRequest,
        q: &[f64],
        now: Time,
    ) -> Result<DMatrix<f64>, NodeError> {
        let n = 2 * self.robot.model().nv;
        if req.start_covariance.is_empty() {
            let state = self.robot.state();
            let age = InputAges::at(state, &self.params.common.state, now).oldest();
            return Ok(self.start_covariance.at(self.robot.model(), q, state, age));
        }
        if req.start_covariance.len() != n * n {
            return Err(NodeError::request(
                "start_covariance",
                format!(
                    "{} entries: must be empty or n × n = {} (n = 2 nv = {n})",
                    req.start_covariance.len(),
                    n * n
                ),
            ));
        }
        // The core checks finiteness, symmetry and the diagonal, naming the entry.
        Ok(DMatrix::from_row_slice(n, n, &req.start_covariance))
    }

    fn try_predict(
        &mut self,
        req: &PredictRequest,
        now: Time,
    ) -> Result<PredictResponse, NodeError> {
        self.check_limits(req)?;
        let common = &self.params.common;
        let (q, v) =
            self.robot
                .request_state(common, req.use_latest_state, (&[], &req.q), (&[], &req.v))?;
        let cmd = &self.params.node.command;
        let mut commands = Vec::with_capacity(req.commands.len().max(1));
        for (k, t) in req.commands.iter().enumerate() {
            let base = self.robot.twist_command(t, &format!("commands[{k}]"))?;
            let at = k as f64 * req.command_period;
            commands.push((at, self.robot.command(Some(base), &q, cmd.hold_joints)));
        }
        if commands.is_empty() {
            let base = self.robot.fallback_twist(cmd.fallback, &v);
            commands.push((0.0, self.robot.command(base, &q, cmd.hold_joints)));
        }
        let p0 = match req.with_covariance {
            true => Some(self.request_covariance(req, &q, now)?),
            false => None,
        };
        let request = PredictionRequest {
            commands: &commands,
            horizon: Some(req.horizon),
            start_covariance: p0.as_ref(),
            forces: req.with_forces,
            // μ where a contact declares none, N of a planar base's wheels: the parameters'.
            contact_limits: self.robot.contact_limits(common),
            lagged_command: lag_start(self.predictor.config().actuators(), &v),
            ..PredictionRequest::new(&q, &v)
        };
        let traj = self
            .predictor
            .predict(&request)
            .map_err(NodeError::core("prediction"))?;
        let frame = &common.frames.odom_frame;
        let path = path_msg(self.robot.model(), &traj, now, frame);
        let forces = traj
            .samples
            .iter()
            .filter_map(|s| {
                let at = ForcesAt::of_sample(s)?;
                Some(self.robot.forces_msg(common, &at, time_plus(now, s.t)))
            })
            .collect();
        let last = traj
            .samples
            .last()
            .ok_or_else(|| NodeError::request("horizon", "the prediction has no samples"))?;
        let n = 2 * self.robot.model().nv;
        let covariances: Vec<f64> = traj
            .samples
            .iter()
            .filter_map(|s| s.covariance.as_ref())
            .flat_map(|p| p.iter().flatten().copied())
            .collect();
        Ok(PredictResponse {
            covariance_dimension: if req.with_covariance { n as u32 } else { 0 },
            covariances,
            success: true,
            message: format!(
                "{} samples, {} steps in {:.3} ms ({:?}){}",
                traj.samples.len(),
                traj.steps,
                traj.run_time_s * 1e3,
                traj.method,
                // With forces, the first slip or lift-off along the horizon.
                traj.first_contact_break()
                    .map(|b| format!("; {}", crate::predictor::contact_break::warning(b)))
                    .unwrap_or_default()
            ),
            path,
            times: traj.samples.iter().map(|s| s.t).collect(),
            forces,
            position_error_estimate: last.position_error_estimate(),
            orientation_error_estimate: last.orientation_error_estimate(),
            // 0 when the scene turns the estimate off, as the base's integration part.
            joint_error_estimate_rad: last.error_estimate_by_kind.map_or(0.0, |e| e.joint_rad),
            joint_error_estimate_m: last.error_estimate_by_kind.map_or(0.0, |e| e.joint_m),
        })
    }
}

/// Where a request's command lag starts (a scene with `actuators.diff_drive.command_lag`): at
/// the start's wheel speeds, the drive's lagged targets that its wheel loops track. A request
/// carries no command history, and its first command is what a planner asks about, not what
/// the drive already follows: started on it, the drive would answer it with no lag at all.
fn lag_start(actuators: &Actuators, v: &[f64]) -> Option<[f64; 2]> {
    actuators.command_lag_s()?;
    actuators.drive_command_of_wheels(v)
}
