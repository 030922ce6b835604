//! The predictor scoring its own past predictions (the core's [`PredictionMonitor`]): each
//! periodic prediction's samples at `monitor.horizons` are recorded, due at the start state's
//! odometry stamp + the sample's time; each `odom` and `joint_states` that arrives scores the
//! ones due (no allocation per message). Every tick the figures go out on
//! `~/prediction_residuals` (`diagnostic_msgs/DiagnosticArray`, one status per horizon), the
//! verdict into the node's `/diagnostics` status, and a WARN naming the likely cause once per
//! onset (an INFO when it clears).

use constraint_dynamics::model::Model;
use constraint_dynamics::monitor::{
    HorizonReport, MeasuredOdometry, PlanarCovariance, PredictedSample, PredictionMonitor, Verdict,
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
    /// Whether a joint state with efforts came: predictions before it start from the scene's
    /// initial joints, and their efforts are not scored.
    efforts_seen: bool,
    /// Which joints (v index) the current joint state gave an effort for.
    measured: Vec<bool>,
    /// Joint names by v index (learned from joint states; "" until seen).
    names: Vec<String>,
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
            efforts_seen: false,
            measured: vec![false; nv],
            names: vec![String::new(); nv],
            verdict: None,
            values: Vec::new(),
        }
    }

    fn seconds(&mut self, t: Time) -> f64 {
        let ns = t.to_nanos();
        let epoch = *self.epoch.get_or_insert(ns);
        (ns - epoch) as f64 * 1e-9
    }

    /// Records `traj`'s samples at the monitored horizons, started from the last odometry. Their covariance is the predicted odometry's: propagated (when
    /// the samples carry it) plus the integration error estimate and `floors`.
    pub fn record(&mut self, model: &Model, traj: &Trajectory, floors: &CovarianceParams) {
        // Before the first odometry the prediction starts from the scene's initial state, not
        // from anything measured: nothing to score.
        let Some(t0) = self.odom_t else {
            return;
        };
        let Some(last_t) = traj.samples.last().map(|s| s.t) else {
            return;
        };
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
            covariance[0][0] += sp * sp;
            covariance[1][1] += sp * sp;
            covariance[2][2] += so * so;
            let pose = model.base_pose(&s.q);
            let [x, y, z, w] = pose.orientation_xyzw;
            let yaw = yaw(&Quaternion { x, y, z, w });
            self.core.record(
                i,
                &PredictedSample {
                    t: t0 + s.t,
                    pose: [pose.position[0], pose.position[1], yaw],
                    covariance,
                    effort: match self.efforts_seen {
                        true => &s.actuator_torque,
                        false => &[],
                    },
                },
            );
        }
    }

    /// Scores the predictions due by `od`'s stamp.
    pub fn odometry(&mut self, od: &Odometry) {
        let t = self.seconds(od.header.stamp);
        self.odom_t = Some(t);
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

    /// Scores the predictions due by `js`'s stamp against the efforts it gave (already applied
    /// to `state`).
    pub fn joint_state(&mut self, js: &JointState, state: &StateEstimate) {
        if js.effort.len() != js.name.len() || js.effort.is_empty() {
            return;
        }
        self.measured.fill(false);
        for name in &js.name {
            if let Some((_, iv)) = state.joint(name)
                && iv < self.measured.len()
            {
                self.measured[iv] = true;
                if self.names[iv].is_empty() {
                    self.names[iv] = name.clone();
                }
            }
        }
        self.efforts_seen = true;
        let t = self.seconds(js.header.stamp);
        self.core.efforts(t, &state.effort, &self.measured);
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
        let reports = self.core.reports();
        let status = reports
            .iter()
            .map(|r| status(r, &warning, &names))
            .collect();
        self.values = reports.last().map_or(Vec::new(), |r| values(r, &names));
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
fn status(r: &HorizonReport, warning: &Option<String>, names: &[String]) -> DiagnosticStatus {
    let (level, message) = match warning {
        Some(w) => (DiagnosticStatus::WARN, w.clone()),
        None => (DiagnosticStatus::OK, "predictions match".to_string()),
    };
    DiagnosticStatus {
        level,
        name: format!("prediction at {} s", r.horizon),
        message,
        hardware_id: String::new(),
        values: values(r, names),
    }
}

fn values(r: &HorizonReport, names: &[String]) -> Vec<KeyValue> {
    let h = r.horizon;
    let (joint, effort) = match r.effort_worst {
        Some((j, e)) => (names.get(j).cloned().unwrap_or_default(), format!("{e:.3}")),
        None => (String::new(), "nan".to_string()),
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
        kv("unmatched predictions", &r.unmatched.to_string()),
    ]
}
