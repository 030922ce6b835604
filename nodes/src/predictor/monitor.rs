//! The predictor scoring its own past predictions (the core's [`PredictionMonitor`]): each
//! periodic prediction's samples at `monitor.horizons` are recorded, due at the start state's
//! odometry stamp + the sample's time; each `odom` and `joint_states` that arrives scores the
//! ones due (no allocation per message); a command that moves off the last one by more than
//! `monitor.command_tolerance` (at its arrival on the ROS clock) unscores the predictions it
//! falls within. Every tick the figures go out on
//! `~/prediction_residuals` (`diagnostic_msgs/DiagnosticArray`, one status per horizon), the
//! verdict into the node's `/diagnostics` status, and a WARN naming the likely cause once per
//! onset (an INFO when it clears). Each tick's measured start state also tells how far it lay
//! off the velocity constraints ([`OnlineMonitor::measured_state`]): the slip statistic.

use constraint_dynamics::model::Model;
use constraint_dynamics::monitor::{
    HorizonReport, MeasuredOdometry, PlanarCovariance, PredictedSample, PredictionMonitor,
    ResponseFit, SlipReport, Verdict, yaw_difference,
};
use constraint_dynamics::predict::Trajectory;

use crate::covariance::odometry_covariance;
use crate::msg::builtin_interfaces::Time;
use crate::msg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use crate::msg::geometry_msgs::Quaternion;
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;
use crate::msg::std_msgs::Header;
use crate::node::health::kv;
use crate::robot::state::StateEstimate;
use crate::ros::logging::NodeLog;

use super::params::{CovarianceParams, MonitorParams};

/// REP-103 indices of x, y and yaw in a 6×6 pose covariance.
const XY_YAW: [usize; 3] = [0, 1, 5];

/// The predictor's monitor and what it needs between messages.
pub struct OnlineMonitor {
    core: PredictionMonitor,
    /// The first stamp seen [ns]: times are seconds after it (f64 keeps ns resolution).
    epoch: Option<i64>,
    /// The last odometry's stamp [s after epoch]: the start of the next prediction.
    odom_t: Option<f64>,
    /// The last odometry's forward speed [m/s] and turn rate [rad/s]: a prediction's measured
    /// start velocity.
    odom_velocity: [f64; 2],
    /// Whether a joint state with positions, and one with efforts, came: predictions before
    /// them start from the scene's initial joints, and those are not scored.
    positions_seen: bool,
    efforts_seen: bool,
    /// The current joint state's positions and efforts by v index (NaN: not in it).
    measured_position: Vec<f64>,
    measured_effort: Vec<f64>,
    /// A prediction's joint positions by v index (NaN: not a joint the joint states give).
    predicted_position: Vec<f64>,
    /// Joint names and q indices by v index (learned from joint states; "", None until seen).
    names: Vec<String>,
    q_index: Vec<Option<usize>>,
    /// The command (v [m/s], ω [rad/s]) the last change was judged from, and the tolerance.
    command: Option<[f64; 2]>,
    command_tolerance: [f64; 2],
    /// The model error's σ per metre travelled and per radian turned over a horizon.
    motion_error: [f64; 2],
    verdict: Verdict,
    /// The longest horizon's figures at the last tick, for `/diagnostics`.
    values: Vec<KeyValue>,
}

fn yaw(q: &Quaternion) -> f64 {
    (2.0 * (q.w * q.z + q.x * q.y)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z))
}

impl OnlineMonitor {
    /// A monitor of `nv` joint efforts, for predictions at `rate` [Hz].
    pub fn new(p: &MonitorParams, rate: f64, nv: usize) -> Self {
        OnlineMonitor {
            core: PredictionMonitor::new(p.settings(rate), nv),
            epoch: None,
            odom_t: None,
            odom_velocity: [f64::NAN; 2],
            positions_seen: false,
            efforts_seen: false,
            measured_position: vec![f64::NAN; nv],
            measured_effort: vec![f64::NAN; nv],
            predicted_position: vec![f64::NAN; nv],
            names: vec![String::new(); nv],
            q_index: vec![None; nv],
            command: None,
            command_tolerance: p.command_tolerance(),
            motion_error: p.motion_error(),
            verdict: None,
            values: Vec::new(),
        }
    }

    fn seconds(&mut self, t: Time) -> f64 {
        let ns = t.to_nanos();
        let epoch = *self.epoch.get_or_insert(ns);
        (ns - epoch) as f64 * 1e-9
    }

    /// Records `traj`'s samples at the monitored horizons, started from the last odometry.
    /// Their covariance is the predicted odometry's: propagated (when the samples carry it)
    /// plus the integration error estimate and `floors`, plus the model error the motion
    /// brings (`monitor.motion_error` × the distance travelled and the angle turned from the
    /// start).
    /// The horizons scored [s]: [`Self::record`] reads the covariance of the sample nearest
    /// each.
    pub fn horizons(&self) -> &[f64] {
        &self.core.settings().horizons
    }

    pub fn record(&mut self, model: &Model, traj: &Trajectory, floors: &CovarianceParams) {
        // Before the first odometry the prediction starts from the scene's initial state, not
        // from anything measured: nothing to score.
        let Some(t0) = self.odom_t else {
            return;
        };
        let (Some(first), Some(last_t)) = (traj.samples.first(), traj.samples.last().map(|s| s.t))
        else {
            return;
        };
        let planar = |q: &[f64]| {
            let pose = model.base_pose(q);
            let [x, y, z, w] = pose.orientation_xyzw;
            [
                pose.position[0],
                pose.position[1],
                yaw(&Quaternion { x, y, z, w }),
            ]
        };
        let start = planar(&first.q);
        for i in 0..self.core.settings().horizons.len() {
            let h = self.core.settings().horizons[i];
            if h > last_t + 1e-9 {
                continue;
            }
            let Some(s) = traj
                .samples
                .iter()
                .min_by(|a, b| (a.t - h).abs().total_cmp(&(b.t - h).abs()))
            else {
                continue;
            };
            let err = s.position_error_estimate();
            let (sp, so) = (
                err.hypot(floors.position_floor),
                err.hypot(floors.orientation_floor),
            );
            let pose6 = match &s.covariance {
                Some(p) => odometry_covariance(model, &s.q, p).0,
                None => [0.0; 36],
            };
            let mut covariance: PlanarCovariance = [[0.0; 3]; 3];
            for (a, &ia) in XY_YAW.iter().enumerate() {
                for (b, &ib) in XY_YAW.iter().enumerate() {
                    covariance[a][b] = pose6[6 * ia + ib];
                }
            }
            let pose = planar(&s.q);
            let travelled = (pose[0] - start[0]).hypot(pose[1] - start[1]);
            let turned = yaw_difference(pose[2], start[2]).abs();
            let (mt, mr) = (
                self.motion_error[0] * travelled,
                self.motion_error[1] * turned,
            );
            covariance[0][0] += sp * sp + mt * mt;
            covariance[1][1] += sp * sp + mt * mt;
            covariance[2][2] += so * so + mr * mr;
            for (p, iq) in self.predicted_position.iter_mut().zip(&self.q_index) {
                *p = iq.and_then(|iq| s.q.get(iq).copied()).unwrap_or(f64::NAN);
            }
            self.core.record(
                i,
                &PredictedSample {
                    start: t0,
                    t: t0 + s.t,
                    pose,
                    covariance,
                    effort: match self.efforts_seen {
                        true => &s.actuator_torque,
                        false => &[],
                    },
                    position: match self.positions_seen {
                        true => &self.predicted_position,
                        false => &[],
                    },
                    command: self.command.unwrap_or([f64::NAN; 2]),
                    start_velocity: self.odom_velocity,
                },
            );
        }
    }

    /// Scores the predictions due by `od`'s stamp.
    pub fn odometry(&mut self, od: &Odometry) {
        let t = self.seconds(od.header.stamp);
        self.odom_t = Some(t);
        self.odom_velocity = [od.twist.twist.linear.x, od.twist.twist.angular.z];
        let p = &od.pose.pose;
        let c = &od.pose.covariance;
        let tw = &od.twist.twist;
        self.core.odometry(&MeasuredOdometry {
            t,
            pose: [p.position.x, p.position.y, yaw(&p.orientation)],
            covariance: XY_YAW.map(|i| XY_YAW.map(|j| c[6 * i + j])),
            twist: [tw.linear.x, tw.linear.y, tw.angular.z],
        });
    }

    /// Scores the predictions due by `js`'s stamp against the positions and efforts it gave
    /// (already applied to `state`, and read from there: one value per joint).
    pub fn joint_state(&mut self, js: &JointState, state: &StateEstimate) {
        let has_position = js.position.len() == js.name.len() && !js.name.is_empty();
        let has_effort = js.effort.len() == js.name.len() && !js.name.is_empty();
        if !(has_position || has_effort) {
            return;
        }
        self.measured_position.fill(f64::NAN);
        self.measured_effort.fill(f64::NAN);
        for name in &js.name {
            let Some((iq, iv)) = state.joint(name) else {
                continue;
            };
            if iv >= self.names.len() {
                continue;
            }
            if self.names[iv].is_empty() {
                self.names[iv] = name.clone();
                self.q_index[iv] = Some(iq);
            }
            if has_position {
                self.measured_position[iv] = state.q.get(iq).copied().unwrap_or(f64::NAN);
            }
            if has_effort {
                self.measured_effort[iv] = state.effort[iv];
            }
        }
        self.positions_seen |= has_position;
        self.efforts_seen |= has_effort;
        let t = self.seconds(js.header.stamp);
        (self.core).joint_states(t, &self.measured_position, &self.measured_effort);
    }

    /// The tick's measured start state lay `velocity_residual` ‖J v‖ [m/s or rad/s] off the
    /// velocity constraints before its projection.
    pub fn measured_state(&mut self, velocity_residual: f64) {
        self.core.measured_state(velocity_residual);
    }

    /// A command (v [m/s], ω [rad/s]) arrived at `now`: one off the last by more than the
    /// tolerance changes what the pending predictions assumed.
    pub fn command(&mut self, now: Time, command: [f64; 2]) {
        let tol = self.command_tolerance;
        let changed = match self.command {
            None => true,
            Some(c) => (0..2).any(|i| (command[i] - c[i]).abs() > tol[i]),
        };
        if changed {
            self.command = Some(command);
            let t = self.seconds(now);
            self.core.command_changed(t);
        }
    }

    /// The verdict's sentence (None while the model matches).
    pub fn warning(&self) -> Option<String> {
        let names = &self.names;
        let name = |j: usize| match names.get(j) {
            Some(n) if !n.is_empty() => n.clone(),
            _ => format!("joint (v index {j})"),
        };
        self.verdict.map(|c| c.describe(&name))
    }

    /// Assesses the latest figures: logs an onset (WARN) or a clearing (INFO), and returns the
    /// report for `~/prediction_residuals` stamped `now`.
    pub fn tick(&mut self, now: Time, log: &NodeLog) -> DiagnosticArray {
        let (verdict, changed) = self.core.assess();
        self.verdict = verdict;
        if changed {
            match self.warning() {
                Some(w) => log.warn(&format!("predictions off what arrives: {w}")),
                None => log.info("predictions match what arrives again"),
            }
        }
        let warning = self.warning();
        let names = self.names.clone();
        let slip = self.core.slip_report();
        let reports = self.core.reports();
        let status = reports
            .iter()
            .map(|r| status(r, &slip, &warning, &names))
            .collect();
        self.values = reports
            .last()
            .map_or(Vec::new(), |r| values(r, &slip, &names));
        DiagnosticArray {
            header: Header {
                stamp: now,
                frame_id: String::new(),
            },
            status,
        }
    }

    /// `/diagnostics` values: the longest horizon's figures at the last tick.
    pub fn key_values(&self) -> &[KeyValue] {
        &self.values
    }
}

/// One horizon's status on `~/prediction_residuals`.
fn status(
    r: &HorizonReport,
    slip: &SlipReport,
    warning: &Option<String>,
    names: &[String],
) -> DiagnosticStatus {
    let (level, message) = match warning {
        Some(w) => (DiagnosticStatus::WARN, w.clone()),
        None => (DiagnosticStatus::OK, "predictions match".to_string()),
    };
    DiagnosticStatus {
        level,
        name: format!("prediction at {} s", r.horizon),
        message,
        hardware_id: String::new(),
        values: values(r, slip, names),
    }
}

fn values(r: &HorizonReport, slip: &SlipReport, names: &[String]) -> Vec<KeyValue> {
    let h = r.horizon;
    let worst = |w: Option<(usize, f64)>, digits: usize| match w {
        Some((j, e)) => (
            names.get(j).cloned().unwrap_or_default(),
            format!("{e:.digits$}"),
        ),
        None => (String::new(), "nan".to_string()),
    };
    let (joint, effort) = worst(r.effort_worst, 3);
    let (position_joint, position) = worst(r.joint_position_worst, 5);
    let fit = |value: fn(&ResponseFit) -> f64, digits: usize| match &r.response {
        Some(f) => format!("{:.digits$}", value(f)),
        None => "nan".to_string(),
    };
    vec![
        kv("horizon [s]", &format!("{h}")),
        kv("odometry samples", &r.odometry_samples.to_string()),
        kv(
            "position error median [m]",
            &format!("{:.3e}", r.position_median),
        ),
        kv("yaw error median [rad]", &format!("{:.3e}", r.yaw_median)),
        kv(
            "NEES median (chi2 3: 2.37)",
            &format!("{:.3}", r.nees_median),
        ),
        kv("NEES mean (chi2 3: 3)", &format!("{:.3}", r.nees_mean)),
        kv("effort samples", &r.effort_samples.to_string()),
        kv("worst effort error median [N m or N]", &effort),
        kv("worst effort joint", &joint),
        kv(
            "joint position samples",
            &r.joint_position_samples.to_string(),
        ),
        kv("worst joint position error median [rad or m]", &position),
        kv("worst joint position joint", &position_joint),
        kv("unmatched predictions", &r.unmatched.to_string()),
        kv(
            "command changed (not scored)",
            &r.command_changed.to_string(),
        ),
        kv("drive lag beyond the model [s]", &fit(|f| f.lag_s, 4)),
        kv(
            "drive lag standard error [s]",
            &fit(|f| f.lag_std_error_s, 4),
        ),
        kv(
            "travel beyond the model [fraction of command x horizon]",
            &fit(|f| f.travel_ratio, 4),
        ),
        kv(
            "turn beyond the model [fraction of command x horizon]",
            &fit(|f| f.turn_ratio, 4),
        ),
        kv("measured states (slip)", &slip.samples.to_string()),
        kv(
            "measured state velocity residual median [m/s or rad/s]",
            &format!("{:.3e}", slip.residual_median),
        ),
    ]
}
