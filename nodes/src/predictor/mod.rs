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
pub mod ros;
pub mod smoother;
mod smoother_ros;
mod stale;
mod work;

use std::time::{Duration, Instant};

use constraint_dynamics::Scene;
use constraint_dynamics::algorithm::frame_placement;
use constraint_dynamics::constraints::{ConstraintForce, ContactState};
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::predict::{
    ContactCheck, CovarianceSamples, DriftProjector, OffConstraints, PredictionRequest, Predictor,
    Trajectory,
};
use constraint_dynamics::system::System;

use crate::convert::{ForcesAt, path_msg, pose_msg, time_plus, twist_msg};
use crate::covariance::odometry_covariance;
use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::{AccelerationLimits, ConstraintForces};
use crate::msg::diagnostic_msgs::{DiagnosticArray, KeyValue};
use crate::msg::geometry_msgs::{Twist, WrenchStamped};
use crate::msg::nav_msgs::{Odometry, Path};
use crate::msg::sensor_msgs::JointState;
use crate::msg::std_msgs::Header;
use crate::msg::visualization_msgs::MarkerArray;
use crate::node::health::kv;
use crate::node::worker::NodeLogic;
use crate::params::{NodeParams, StaleBehaviour};
use crate::robot::Robot;
use crate::robot::inputs::{InputAges, StartCovariance};
use crate::ros::logging::{DropLog, NodeLog};
pub use params::{CovarianceParams, EnvelopeParams, MarkerParams, PredictorParams};

/// The fraction of the tick period above which the last tick's covariance propagation moves
/// the next one to a second thread (`Predictor::with_parallel_covariance`). Below it, inline
/// costs less CPU: the default suite's covariance takes about 1 % of its 100 ms period, and a
/// worker thread per tick (its start and hand-offs) cost 0.004–0.007 of a core more.
const PARALLEL_COVARIANCE: f64 = 0.1;

/// What one periodic prediction publishes.
#[derive(Clone, Debug)]
pub struct PeriodicOutput {
    /// The base at the horizon (stamp = start + horizon).
    pub odom: Odometry,
    /// The base along the prediction.
    pub path: Path,
    /// Constraint forces at the start state under the commanded actuator torques.
    pub forces: ConstraintForces,
    /// rviz2: force arrows and the predicted footprint (`markers.enabled`).
    pub markers: Option<MarkerArray>,
    /// Each constraint's wrench in its own frame (`markers.wrenches`): (name, message).
    pub wrenches: Vec<(String, WrenchStamped)>,
    /// The acceleration envelope at the start state (`envelope.enabled`; none when it failed).
    pub limits: Option<AccelerationLimits>,
    /// The base's forward speed at the start state [m/s] (which envelope limits bound a
    /// velocity smoother's acceleration and deceleration).
    pub forward_speed: f64,
    /// The past predictions scored against what arrived (`monitor.enabled`).
    pub residuals: Option<DiagnosticArray>,
    /// Time spent computing [s].
    pub compute_s: f64,
}

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
        let sys = System::from_scene(robot.scene()).map_err(NodeError::core("predictor"))?;
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
        Ok(PredictorNode {
            monitor,
            integrals: Default::default(),
            robot,
            predictor,
            start: (sys, forces),
            params,
            log,
            last_command: None,
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
            let base = self.fresh_command(at).or_else(|| {
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

    /// One periodic prediction from the latest state under `command` (v, ω) — `None` = no
    /// fresh command (the fallback applies) — from a state `age` [s] old.
    pub fn periodic(
        &mut self,
        now: Time,
        command: Option<[f64; 2]>,
        age: f64,
    ) -> Result<PeriodicOutput, NodeError> {
        let t0 = Instant::now();
        let common = &self.params.common;
        let (q, v) = self
            .robot
            .latest_state(common.state.project_to_constraints)?;
        let cmd_params = &self.params.node.command;
        let base = command.or_else(|| self.robot.fallback_twist(cmd_params.fallback, &v));
        let cmd = self.robot.command(base, &q, cmd_params.hold_joints);
        let p0 = match self.params.node.covariance.propagate {
            true => {
                self.start_covariance
                    .nonzero_at(self.robot.model(), &q, self.robot.state(), age)
            }
            false => None,
        };
        if self.params.node.horizon().is_none() && self.predictor.config().settings().horizon <= 0.0
        {
            return Err(NodeError::request(
                "horizon",
                "0 s: set `horizon` or the scene's integration.horizon",
            ));
        }
        let commands = [(0.0, cmd)];
        let request = PredictionRequest {
            commands: &commands,
            horizon: self.params.node.horizon(),
            start_covariance: p0.as_ref(),
            // The odometry carries P at the horizon only; the monitor reads the samples nearest
            // its horizons.
            covariance_samples: match &self.monitor {
                Some(m) => CovarianceSamples::Near(m.horizons()),
                None => CovarianceSamples::Last,
            },
            // Every sample's contacts judged: no prediction drives past a slip or a lift-off
            // unsaid (`/diagnostics`).
            forces: true,
            contact_limits: self.robot.contact_limits(common),
            controller_integrals: match common.state.controller_integrals_from_effort {
                true => self.integrals.get(),
                false => &[],
            },
            ..PredictionRequest::new(&q, &v)
        };
        // The covariance on a second thread only where it is a large part of the period: a
        // worker started every tick costs more CPU than it saves when the covariance is light.
        let period = 1.0 / self.params.node.rate;
        let heavy = |w: &work::PredictionWork| w.covariance_s > PARALLEL_COVARIANCE * period;
        (self.predictor).set_parallel_covariance(self.work.as_ref().is_some_and(heavy));
        let traj = self
            .predictor
            .predict(&request)
            .map_err(NodeError::core("prediction"))?;
        let odom = self.odometry_at_horizon(&traj, now)?;
        let path = path_msg(self.robot.model(), &traj, now, &common.frames.odom_frame);
        // Forces at the start state, under the torques the controllers apply in the first tick:
        // the prediction's first sample, its contacts judged as every sample's are.
        let zero = vec![0.0; self.robot.model().nv];
        let at = ForcesAt::of_sample(&traj.samples[0]).unwrap_or(ForcesAt {
            generalized_force: &zero, // no constraints: no forces
            ..ForcesAt::default()
        });
        let forces = self.robot.forces_msg(common, &at, now);
        let judged = at.judged(self.robot.contact_judge());
        let states: Vec<Option<ContactState>> = judged.iter().map(|j| j.map(|(_, s)| s)).collect();
        let measured_off = match common.state.project_to_constraints {
            true => self.robot.off_constraints().map(|o| o.velocity_residual),
            false => traj.start_off_constraints.map(|o| o.velocity_residual),
        };
        (self.break_log).update(
            &self.log,
            &forces,
            &judged,
            &request.contact_limits,
            measured_off,
        );
        self.slipping = forces
            .constraints
            .iter()
            .filter(|c| c.slipping)
            .map(|c| c.name.clone())
            .collect();
        self.position_residual = traj.samples.last().map_or(0.0, |s| s.position_residual);
        // Projected here (`state.project_to_constraints`), else by the prediction for its forces.
        self.start_off_constraints = match common.state.project_to_constraints {
            true => self.robot.off_constraints(),
            false => traj.start_off_constraints,
        };
        let (markers, wrenches) = self.markers(at.forces, &states, &q, &path, now);
        // Nobody taking the limits, the envelope is only for `/diagnostics`: once per period of
        // its status (its SOCPs cost a quarter of the prediction's instructions).
        let since = |t: &Time| (now.to_nanos() - t.to_nanos()) as f64 * 1e-9;
        let period = self.params.common.diagnostics.period;
        let envelope_due = self.limits_wanted
            || (self.envelope_at.as_ref()).is_none_or(|t| !(0.0..period).contains(&since(t)));
        let limits = match self.params.node.envelope.enabled && envelope_due {
            true => {
                self.envelope_at = Some(now);
                let (sys, elements) = &mut self.start;
                // The envelope holds the rows as equalities, which a state off the constraints
                // cannot meet: without `state.project_to_constraints` it takes the projection
                // the prediction's start forces took.
                let (mut qe, mut ve) = (q.clone(), v.clone());
                if !self.params.common.state.project_to_constraints {
                    (DriftProjector::new(sys).project_measured(sys, &mut qe, &mut ve)).map_err(
                        NodeError::core("start state: projection onto the constraints"),
                    )?;
                }
                let frame = self.robot.base_frame();
                let mu = self.params.common.slip.friction_coefficient;
                self.envelope
                    .at(sys, elements, (&qe, &ve), mu, (now, frame), &self.log)
            }
            false => None,
        };
        let forward_speed = self.robot.model().base_twist(&v).linear[0];
        let residuals = self.monitor.as_mut().map(|m| {
            let floors = &self.params.node.covariance;
            m.record(self.robot.model(), &traj, floors);
            m.tick(now, &self.log)
        });
        let compute_s = t0.elapsed().as_secs_f64();
        self.work = Some(work::PredictionWork::of(&traj, compute_s));
        self.contacts = traj.contact_check;
        Ok(PeriodicOutput {
            odom,
            path,
            forces,
            markers,
            wrenches,
            limits,
            forward_speed,
            residuals,
            compute_s,
        })
    }

    /// The rviz2 markers and wrenches of one prediction: the forces at the start state `q`
    /// with each constraint's contact judged there (`None`: not a contact), the footprint along
    /// `path`.
    fn markers(
        &mut self,
        forces: &[ConstraintForce],
        contacts: &[Option<ContactState>],
        q: &[f64],
        path: &Path,
        now: Time,
    ) -> (Option<MarkerArray>, Vec<(String, WrenchStamped)>) {
        let p = &self.params.node.markers;
        let common = &self.params.common;
        let sys = &mut self.start.0;
        sys.placements_at(q);
        let sys = &*sys;
        // Frame axes → world at the start state (the forces' state).
        let rotation = |frame: &str| -> Option<markers::Rotation> {
            let id = sys.model().frame_id(frame).ok()?;
            let r = frame_placement(sys.model(), sys.data(), id).rotation;
            Some([0, 1, 2].map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]))
        };
        let style = markers::MarkerStyle {
            force_scale: p.force_scale,
            arrow_width: p.arrow_width,
            // A few periods, at least 1 s: markers vanish soon after predictions stop.
            lifetime: (3.0 / self.params.node.rate).max(1.0),
            line_width: 0.5 * p.arrow_width,
        };
        let out = p.enabled.then(|| {
            let header = Header {
                stamp: now,
                frame_id: common.frames.odom_frame.clone(),
            };
            let mut m = markers::force_markers(forces, contacts, &rotation, &header, &style);
            m.push(markers::footprint_marker(
                path,
                &p.polygon(),
                p.footprint_period,
                now,
                &style,
            ));
            MarkerArray { markers: m }
        });
        let wrenches = match p.wrenches {
            true => markers::constraint_wrenches(forces, &rotation, &common.frames.odom_frame, now),
            false => Vec::new(),
        };
        (out, wrenches)
    }

    fn odometry_at_horizon(&self, traj: &Trajectory, start: Time) -> Result<Odometry, NodeError> {
        let model = self.robot.model();
        let last = traj
            .samples
            .last()
            .ok_or_else(|| NodeError::request("horizon", "the prediction has no samples"))?;
        // The base's own estimates, in m and rad (not the joints': a wheel's angle is 1/r × the
        // travel).
        let c = &self.params.node.covariance;
        let sp = last.position_error_estimate().hypot(c.position_floor);
        let so = last.orientation_error_estimate().hypot(c.orientation_floor);
        let st = c.twist_floor;
        let (mut pose_cov, mut twist_cov) = match &last.covariance {
            Some(p) => odometry_covariance(model, &last.q, p),
            None => ([0.0; 36], [0.0; 36]),
        };
        // The propagated covariance plus, independent of it, the integration error estimate
        // and the floors (model error the process noise may not cover); on every axis, so a
        // planar base's z, roll and pitch carry the floors (robot_localization's "implicit
        // zero measurement" of a platform constraint: small, not inflated).
        for (i, s) in [sp, sp, sp, so, so, so].into_iter().enumerate() {
            pose_cov[7 * i] += s * s;
            twist_cov[7 * i] += st * st;
        }
        if let Some(x) = pose_cov.iter().chain(&twist_cov).find(|x| !x.is_finite()) {
            return Err(NodeError::request(
                "predicted covariance",
                format!("is not finite ({x}): reduce the start covariance or the horizon"),
            ));
        }
        let mut odom = Odometry {
            header: Header {
                stamp: time_plus(start, last.t),
                frame_id: self.params.common.frames.odom_frame.clone(),
            },
            child_frame_id: self.robot.base_frame().to_string(),
            ..Default::default()
        };
        odom.pose.pose = pose_msg(&model.base_pose(&last.q));
        odom.pose.covariance = pose_cov;
        odom.twist.twist = twist_msg(&model.base_twist(&last.v));
        odom.twist.covariance = twist_cov;
        Ok(odom)
    }
}

#[cfg(test)]
mod limits_wanted_tests;
#[cfg(test)]
mod start_state_tests;
#[cfg(test)]
mod tests;
