//! `cd_predictor`: at its rate, predicts from the latest state under the latest command and
//! publishes the base at the horizon (`~/predicted_odom`), the path (`~/predicted_path`) and the
//! constraint forces at the current state (`~/constraint_forces`, the prediction's first
//! sample), with its contacts' slips and lift-offs logged, and the acceleration envelope at that state (`~/acceleration_limits`, [`envelope`]),
//! which may also drive a velocity smoother's limits ([`smoother`]). Everything the predictor decides to publish is decided in [`PredictorNode::periodic`].
//!
//! The predicted odometry carries the covariance the core propagates from the start covariance
//! of the inputs ([`inputs`]); inputs older than `state.timeout` stop the predictions or, with
//! `state.stale_behaviour: warn`, are used with a WARN and a covariance grown with their age.

pub(crate) mod contact_break;
mod controller_state;
pub mod envelope;
pub mod markers;
mod monitor;
mod monitor_params;
pub mod params;
mod periodic;
pub mod ros;
pub mod smoother;
mod smoother_ros;
mod stale;
mod work;

use std::time::{Duration, Instant};

use constraint_dynamics::Scene;
use constraint_dynamics::actuators::CommandLag;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::predict::{ContactCheck, OffConstraints, Predictor};
use constraint_dynamics::system::System;

use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::diagnostic_msgs::KeyValue;
use crate::msg::geometry_msgs::Twist;
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;
use crate::node::health::kv;
use crate::node::worker::NodeLogic;
use crate::params::{NodeParams, StaleBehaviour};
use crate::robot::Robot;
use crate::robot::inputs::{InputAges, StartCovariance};
use crate::ros::logging::{DropLog, NodeLog};
pub use params::{CovarianceParams, EnvelopeParams, MarkerParams, PredictorParams};
pub use periodic::PeriodicOutput;

/// What the predictor reacts to.
pub enum PredictorInput {
    /// A velocity command (the command to predict under).
    Command(Twist),
    /// Whether anything takes the envelope at every tick (a subscriber of
    /// `~/acceleration_limits` or the velocity smoother bridge); without, it is computed once
    /// per diagnostics period, for `/diagnostics` only (see [`PredictorNode::periodic`]).
    LimitsWanted(bool),
}

/// The predictor's logic: a robot, its predictor, the latest command and the slip log.
pub struct PredictorNode {
    robot: Robot,
    predictor: Predictor,
    /// The system and force elements of the envelope and the markers' frame rotations at the
    /// start state (apart from the predictor's, whose workspace its runs own).
    start: (System, ForceElements),
    params: NodeParams<PredictorParams>,
    log: NodeLog,
    /// Latest (v, ω) command and when it arrived (ROS time: /clock under `use_sim_time`).
    last_command: Option<([f64; 2], Time)>,
    /// The drive's lagged command over the commands received, where the scene declares a
    /// `command_lag` (ROS time [s]).
    command_lag: Option<CommandLag>,
    /// One WARN per reason a command is only partly used, per window.
    command_log: DropLog,
    /// The contacts' breaks at the last prediction's start, logged as they change.
    break_log: contact_break::BreakLog,
    /// Contacts slipping or lifting off at the last prediction's start (for `/diagnostics`).
    slipping: Vec<String>,
    /// max |φ| at the last prediction's horizon [m or rad] (for `/diagnostics`).
    position_residual: f64,
    /// How far the last start state lay off the constraints before its projection (for
    /// `/diagnostics`).
    start_off_constraints: Option<OffConstraints>,
    /// How the inputs' covariances become the start covariance.
    start_covariance: StartCovariance,
    /// The stale inputs at the last tick ("odom 0.62 s"), empty when fresh.
    stale: Vec<String>,
    /// The last periodic prediction's work (for `/diagnostics`).
    work: Option<work::PredictionWork>,
    /// The contacts judged along the last prediction: its first slip or lift-off is a WARN.
    contacts: Option<ContactCheck>,
    /// The acceleration envelope at the start state (with its own model and workspace).
    envelope: envelope::StartEnvelope,
    /// Whether the envelope is wanted at every tick ([`PredictorInput::LimitsWanted`]), and
    /// when it was last computed.
    limits_wanted: bool,
    envelope_at: Option<Time>,
    /// Scores past predictions against the odometry and joint states (`monitor.enabled`).
    monitor: Option<monitor::OnlineMonitor>,
    /// The wheel controllers' integrals from the last joint state's efforts.
    integrals: controller_state::ControllerIntegrals,
}

impl NodeLogic for PredictorNode {
    type Params = PredictorParams;
    type Input = PredictorInput;
    type Output = Box<PeriodicOutput>;

    fn new(
        robot: Robot,
        params: NodeParams<PredictorParams>,
        log: NodeLog,
    ) -> Result<Self, NodeError> {
        let predictor =
            Predictor::from_scene(robot.scene()).map_err(NodeError::core("predictor"))?;
        // The start system serves the envelope and the markers' placements: instantaneous
        // answers, rigid sideways (a tyre's creep is no velocity to command).
        let sys = System::from_scene(&robot.scene().rigid_sideways())
            .map_err(NodeError::core("predictor"))?;
        let forces = ForceElements::new(sys.model(), &robot.scene().file.forces)
            .map_err(NodeError::core("predictor"))?;
        let nc = robot.scene().file.constraints.len();
        let path = &params.node.envelope.scene_file;
        let own = match path.is_empty() {
            true => None,
            false => {
                let scene = Scene::load(path).map_err(|source| NodeError::Scene {
                    path: path.clone(),
                    source,
                })?;
                let own = envelope::EnvelopeScene::new(&scene, sys.model()).map_err(|why| {
                    NodeError::request(
                        "envelope.scene_file",
                        format!("{path} cannot take the predictor's state: {why}"),
                    )
                })?;
                Some((own, scene.file.passive_joints))
            }
        };
        let envelope =
            envelope::StartEnvelope::new(&sys, &robot.scene().file.passive_joints, own, &log);
        let start_covariance = StartCovariance::new(
            robot.model(),
            &params.common.state,
            &robot.scene().file.uncertainty,
        )?;
        let p = &params.node;
        let monitor = (p.monitor.enabled)
            .then(|| monitor::OnlineMonitor::new(&p.monitor, p.rate, robot.model().nv));
        let command_lag = (predictor.config().actuators().command_lag_s()).map(CommandLag::new);
        Ok(PredictorNode {
            monitor,
            integrals: Default::default(),
            robot,
            predictor,
            start: (sys, forces),
            params,
            log,
            last_command: None,
            command_lag,
            command_log: DropLog::default(),
            break_log: contact_break::BreakLog::new(nc),
            slipping: Vec::new(),
            position_residual: 0.0,
            start_off_constraints: None,
            start_covariance,
            stale: Vec::new(),
            work: None,
            contacts: None,
            envelope,
            limits_wanted: true,
            envelope_at: None,
        })
    }
    fn robot(&self) -> &Robot {
        &self.robot
    }
    fn robot_mut(&mut self) -> &mut Robot {
        &mut self.robot
    }
    fn params(&self) -> &NodeParams<PredictorParams> {
        &self.params
    }
    fn set_params(&mut self, params: NodeParams<PredictorParams>) {
        self.params = params;
    }
    fn handle(&mut self, input: PredictorInput, now: Time, _out: &mut dyn FnMut(Self::Output)) {
        let t = match input {
            PredictorInput::Command(t) => t,
            PredictorInput::LimitsWanted(wanted) => {
                self.limits_wanted = wanted;
                return;
            }
        };
        let finite = t.linear.x.is_finite() && t.angular.z.is_finite();
        if let Err(e) = self.robot.twist_command(&t, "cmd_vel") {
            let level = self
                .command_log
                .level("command", &e.to_string(), Instant::now());
            self.log.log(
                level,
                &format!("{e}; using linear.x and angular.z if finite"),
            );
        }
        self.last_command = finite.then_some(([t.linear.x, t.angular.z], now));
        if let (Some(lag), Some((c, _))) = (&mut self.command_lag, self.last_command) {
            lag.push(now.to_nanos() as f64 * 1e-9, c);
        }
        if let (Some(m), Some((c, _))) = (&mut self.monitor, self.last_command) {
            m.command(now, c);
        }
    }
    fn odometry_applied(&mut self, od: &Odometry) {
        if let Some(m) = &mut self.monitor {
            m.odometry(od);
        }
    }
    fn joint_state_applied(&mut self, js: &JointState) {
        if let Some(m) = &mut self.monitor {
            m.joint_state(js, self.robot.state());
        }
        if self.params.common.state.controller_integrals_from_effort {
            // The command the controllers followed when the efforts were measured.
            let state = self.robot.state();
            let at = state.joint_states_at.unwrap_or_default();
            let lagged = (self.command_lag).and_then(|l| l.at(at.to_nanos() as f64 * 1e-9));
            let base = lagged.or_else(|| self.fresh_command(at)).or_else(|| {
                let fallback = self.params.node.command.fallback;
                self.robot.fallback_twist(fallback, &state.v)
            });
            let cmd = self.robot.command(base, &state.q, false);
            let actuators = self.predictor.config().actuators();
            self.integrals.joint_state(state, actuators, js, &cmd);
        }
    }
    fn tick_period(&self) -> Option<Duration> {
        Some(Duration::from_secs_f64(1.0 / self.params.node.rate))
    }
    fn tick(&mut self, now: Time, out: &mut dyn FnMut(Self::Output)) -> Result<(), NodeError> {
        let command = self.fresh_command(now);
        let state = &self.params.common.state;
        let ages = InputAges::at(self.robot.state(), state, now);
        let stale = ages.stale(state.timeout);
        let behaviour = state.stale_behaviour;
        self.log_stale(stale);
        if !self.stale.is_empty() && behaviour == StaleBehaviour::Stop {
            return Ok(());
        }
        let o = self.periodic(now, command, ages.oldest())?;
        self.log
            .debug(&format!("prediction took {:.3} ms", o.compute_s * 1e3));
        out(Box::new(o));
        Ok(())
    }
    fn warnings(&self) -> Vec<String> {
        let stale = (!self.stale.is_empty()).then(|| self.stale_message(&self.stale));
        let first_break = self.contacts.as_ref().and_then(|c| c.first_break.as_ref());
        stale
            .into_iter()
            .chain(first_break.map(contact_break::warning))
            .chain(self.envelope.warning())
            .chain(self.monitor.as_ref().and_then(|m| m.warning()))
            .collect()
    }
    fn diagnostics(&self) -> Vec<KeyValue> {
        let inputs = match self.stale.is_empty() {
            true => "fresh".to_string(),
            false => self.stale_message(&self.stale),
        };
        let mut values = vec![
            kv("state inputs", &inputs),
            kv("slipping contacts", &self.slipping.join(", ")),
            kv(
                "max position residual [m or rad]",
                &format!("{:.3e}", self.position_residual),
            ),
        ];
        if let Some(o) = &self.start_off_constraints {
            values.push(kv(
                "start state off the constraints",
                &format!(
                    "|φ| {:.3e} m or rad, |J v| {:.3e} m/s or rad/s (projected onto them)",
                    o.position_residual, o.velocity_residual
                ),
            ));
        }
        values.extend(self.work.iter().flat_map(|w| w.key_values()));
        let contacts = self.contacts.iter().flat_map(contact_break::values);
        values.extend(contacts.map(|(key, value)| kv(key, &value)));
        values.extend(self.envelope.key_values());
        values.extend(
            self.monitor
                .iter()
                .flat_map(|m| m.key_values().iter().cloned()),
        );
        values
    }
    fn rate_shortfall(&self) -> Option<String> {
        self.work.as_ref()?.overrun(1.0 / self.params.node.rate)
    }
}

impl PredictorNode {
    /// The last command if it is fresh at `now`: its age on the ROS clock, so a simulation's
    /// time decides when it is stale.
    fn fresh_command(&self, now: Time) -> Option<[f64; 2]> {
        let timeout = self.params.node.command.timeout;
        let age = |at: &Time| (now.to_nanos() - at.to_nanos()) as f64 * 1e-9;
        self.last_command
            .filter(|(_, at)| (0.0..=timeout).contains(&age(at)))
            .map(|(c, _)| c)
    }
}

#[cfg(test)]
mod envelope_tests;
#[cfg(test)]
mod limits_wanted_tests;
#[cfg(test)]
mod start_state_tests;
#[cfg(test)]
mod tests;
