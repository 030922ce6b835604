//! One periodic prediction of [`PredictorNode`] and what it publishes: the base at the horizon
//! with its covariance, the path, the forces at the start state with their contacts judged,
//! the markers and wrenches, the acceleration envelope and the monitor's residuals.

use std::time::Instant;

use constraint_dynamics::algorithm::frame_placement;
use constraint_dynamics::constraints::{ConstraintForce, ContactState};
use constraint_dynamics::predict::{
    CovarianceSamples, DriftProjector, PredictionRequest, Trajectory,
};

use super::{PredictorNode, markers, work};
use crate::convert::{ForcesAt, path_msg, pose_msg, time_plus, twist_msg};
use crate::covariance::odometry_covariance;
use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::{AccelerationLimits, ConstraintForces};
use crate::msg::diagnostic_msgs::DiagnosticArray;
use crate::msg::geometry_msgs::WrenchStamped;
use crate::msg::nav_msgs::{Odometry, Path};
use crate::msg::std_msgs::Header;
use crate::msg::visualization_msgs::MarkerArray;

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

impl PredictorNode {
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
            lagged_command: (self.command_lag).and_then(|l| l.at(now.to_nanos() as f64 * 1e-9)),
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
        let off = self.start_off_constraints.map(|o| o.velocity_residual);
        let residuals = self.monitor.as_mut().map(|m| {
            if let Some(residual) = off {
                m.measured_state(residual);
            }
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
