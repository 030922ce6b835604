//! The latest robot state, assembled from `sensor_msgs/JointState` (joints by name) and
//! `nav_msgs/Odometry` (base pose in the odom frame, twist in the base frame).
//!
//! Starts at the scene's initial state; every message overwrites what it carries. A malformed
//! message is refused as a whole (nothing of it is applied) with a reason.

use std::collections::HashMap;

use constraint_dynamics::model::{BasePose, BaseTwist};
use constraint_dynamics::{BaseType, Model};

use crate::convert::unit_quaternion;
use crate::covariance::check_odometry_covariance;
use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;

/// Latest q (nq), v (nv) and measured joint efforts (nv, 0 where unknown).
#[derive(Clone, Debug)]
pub struct StateEstimate {
    /// Configuration (nq).
    pub q: Vec<f64>,
    /// Velocity (nv).
    pub v: Vec<f64>,
    /// Joint efforts from `JointState.effort`, in v order [N·m or N]; 0 where never given.
    pub effort: Vec<f64>,
    /// Stamp of the last message applied.
    pub stamp: Option<Time>,
    /// The last odometry's pose covariance (odom frame) and twist covariance (base frame),
    /// REP-103 6×6 row-major; zero until one came.
    pub odom_covariance: ([f64; 36], [f64; 36]),
    /// When the last `JointState` / `Odometry` was applied, on the node's ROS clock (set by the
    /// worker: a message's own stamp may come from another clock).
    pub joint_states_at: Option<Time>,
    /// See `joint_states_at`.
    pub odom_at: Option<Time>,
    /// 1-DOF joint name → (q index, v index).
    joints: HashMap<String, (usize, usize)>,
    base: BaseType,
    /// The scene's initial configuration: the height, roll and pitch a planar odometry leaves
    /// unmeasured on a floating base (`Model::keep_unmeasured_tilt`).
    rest: Vec<f64>,
}

/// What a `JointState` did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct JointStateReport {
    /// Joints of the model that were updated.
    pub applied: usize,
    /// Names the model does not have (ignored: fixed, locked or other robots' joints).
    pub unknown: Vec<String>,
}

impl StateEstimate {
    /// At `(q0, v0)` for `model`.
    pub fn new(model: &Model, q0: &[f64], v0: &[f64]) -> Self {
        let joints = model
            .bodies
            .iter()
            .skip(1)
            .map(|b| &b.joint)
            .filter(|j| j.kind.nq() == 1 && j.kind.nv() == 1)
            .map(|j| (j.name.clone(), (j.idx_q, j.idx_v)))
            .collect();
        StateEstimate {
            rest: q0.to_vec(),
            q: q0.to_vec(),
            v: v0.to_vec(),
            effort: vec![0.0; model.nv],
            stamp: None,
            odom_covariance: ([0.0; 36], [0.0; 36]),
            joint_states_at: None,
            odom_at: None,
            joints,
            base: model.base,
        }
    }

    /// The (q index, v index) of a 1-DOF joint.
    pub fn joint(&self, name: &str) -> Option<(usize, usize)> {
        self.joints.get(name).copied()
    }

    /// Applies a `JointState`. Refused (nothing applied) when an array is neither empty nor as
    /// long as `name`, or a value of a known joint is not finite.
    pub fn apply_joint_state(&mut self, js: &JointState) -> Result<JointStateReport, NodeError> {
        let n = js.name.len();
        for (what, len) in [
            ("position", js.position.len()),
            ("velocity", js.velocity.len()),
            ("effort", js.effort.len()),
        ] {
            if len != 0 && len != n {
                return Err(NodeError::message(
                    format!("JointState: {what}"),
                    format!("{len} entries for {n} names (must be 0 or {n})"),
                ));
            }
        }
        let mut updates = Vec::with_capacity(n);
        let mut report = JointStateReport::default();
        for (k, name) in js.name.iter().enumerate() {
            let Some((iq, iv)) = self.joint(name) else {
                report.unknown.push(name.clone());
                continue;
            };
            let get = |a: &[f64], what: &str| -> Result<Option<f64>, NodeError> {
                match a.get(k) {
                    None => Ok(None),
                    Some(x) if x.is_finite() => Ok(Some(*x)),
                    Some(x) => Err(NodeError::message(
                        format!("JointState: {what} of '{name}'"),
                        format!("is {x}"),
                    )),
                }
            };
            updates.push((
                iq,
                iv,
                get(&js.position, "position")?,
                get(&js.velocity, "velocity")?,
                get(&js.effort, "effort")?,
            ));
        }
        for (iq, iv, p, v, e) in updates {
            if let Some(p) = p {
                self.q[iq] = p;
            }
            if let Some(v) = v {
                self.v[iv] = v;
            }
            if let Some(e) = e {
                self.effort[iv] = e;
            }
            report.applied += 1;
        }
        self.stamp = Some(js.header.stamp);
        Ok(report)
    }

    /// Applies an `Odometry`: the base pose (header frame, e.g. odom) and twist (child frame,
    /// the base). A planar base takes x, y, yaw and vx, vy, wz; a floating base all six; a
    /// fixed base ignores it. Refused when a used value is not finite, a used variance is
    /// negative, or the orientation is a zero quaternion.
    pub fn apply_odometry(&mut self, model: &Model, od: &Odometry) -> Result<(), NodeError> {
        let p = &od.pose.pose;
        let t = &od.twist.twist;
        let finite = |what: &str, xs: &[f64]| -> Result<(), NodeError> {
            match xs.iter().find(|x| !x.is_finite()) {
                Some(x) => Err(NodeError::message(
                    format!("Odometry: {what}"),
                    format!("has a non-finite value ({x})"),
                )),
                None => Ok(()),
            }
        };
        let position = [p.position.x, p.position.y, p.position.z];
        let twist = BaseTwist {
            linear: [t.linear.x, t.linear.y, t.linear.z],
            angular: [t.angular.x, t.angular.y, t.angular.z],
        };
        finite("pose.position", &position)?;
        finite("twist", &twist.linear)?;
        finite("twist", &twist.angular)?;
        check_odometry_covariance(model.base, "pose", &od.pose.covariance)?;
        check_odometry_covariance(model.base, "twist", &od.twist.covariance)?;
        let pose = BasePose {
            position,
            orientation_xyzw: unit_quaternion(&p.orientation)
                .map_err(|e| NodeError::message("Odometry: pose.orientation", e.to_string()))?,
        };
        model.set_base(&pose, &twist, &mut self.q, &mut self.v);
        model.keep_unmeasured_tilt(&od.pose.covariance, &self.rest, &mut self.q);
        self.odom_covariance = (od.pose.covariance, od.twist.covariance);
        self.stamp = Some(od.header.stamp);
        Ok(())
    }

    /// Copies what `old` knows into this (a new model of the same robot): the base and every
    /// joint both models have, by name.
    pub fn carry_over(&mut self, old: &StateEstimate) {
        if old.base == self.base {
            let nb = (self.base.nq(), self.base.nv());
            self.q[..nb.0].copy_from_slice(&old.q[..nb.0]);
            self.v[..nb.1].copy_from_slice(&old.v[..nb.1]);
        }
        for (name, &(iq, iv)) in &self.joints {
            if let Some(&(oq, ov)) = old.joints.get(name) {
                self.q[iq] = old.q[oq];
                self.v[iv] = old.v[ov];
                self.effort[iv] = old.effort[ov];
            }
        }
        self.stamp = old.stamp;
        self.odom_covariance = old.odom_covariance;
        self.joint_states_at = old.joint_states_at;
        self.odom_at = old.odom_at;
    }
}
