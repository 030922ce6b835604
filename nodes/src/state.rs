//! The latest robot state, assembled from `sensor_msgs/JointState` (joints by name) and
//! `nav_msgs/Odometry` (base pose in the odom frame, twist in the base frame).
//!
//! Starts at the scene's initial state; every message overwrites what it carries. A malformed
//! message is refused as a whole (nothing of it is applied) with a reason.

use std::collections::HashMap;

use constraint_dynamics::{BaseType, Model};

use crate::convert::unit_quaternion;
use crate::msg::builtin_interfaces::Time;
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;

/// Latest q (nq), v (nv) and measured joint efforts (nv, 0 where unknown).
#[derive(Clone, Debug)]
pub struct StateEstimate {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    /// Joint efforts from `JointState.effort`, in v order [N·m or N]; 0 where never given.
    pub effort: Vec<f64>,
    /// Stamp of the last message applied.
    pub stamp: Option<Time>,
    /// 1-DOF joint name → (q index, v index).
    joints: HashMap<String, (usize, usize)>,
    base: BaseType,
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
            q: q0.to_vec(),
            v: v0.to_vec(),
            effort: vec![0.0; model.nv],
            stamp: None,
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
    pub fn apply_joint_state(&mut self, js: &JointState) -> Result<JointStateReport, String> {
        let n = js.name.len();
        for (what, len) in [
            ("position", js.position.len()),
            ("velocity", js.velocity.len()),
            ("effort", js.effort.len()),
        ] {
            if len != 0 && len != n {
                return Err(format!(
                    "JointState: {what} has {len} entries for {n} names (must be 0 or {n})"
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
            let get = |a: &[f64], what: &str| -> Result<Option<f64>, String> {
                match a.get(k) {
                    None => Ok(None),
                    Some(x) if x.is_finite() => Ok(Some(*x)),
                    Some(x) => Err(format!("JointState: {what} of '{name}' is {x}")),
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
    /// fixed base ignores it. Refused when a used value is not finite or the orientation is
    /// a zero quaternion.
    pub fn apply_odometry(&mut self, od: &Odometry) -> Result<(), String> {
        let p = &od.pose.pose;
        let t = &od.twist.twist;
        let finite = |what: &str, xs: &[f64]| -> Result<(), String> {
            match xs.iter().find(|x| !x.is_finite()) {
                Some(x) => Err(format!("Odometry: {what} has a non-finite value ({x})")),
                None => Ok(()),
            }
        };
        finite("pose.position", &[p.position.x, p.position.y, p.position.z])?;
        finite(
            "twist",
            &[
                t.linear.x,
                t.linear.y,
                t.linear.z,
                t.angular.x,
                t.angular.y,
                t.angular.z,
            ],
        )?;
        let quat = unit_quaternion(&p.orientation).map_err(|e| format!("Odometry: {e}"))?;
        match self.base {
            BaseType::Fixed => {}
            BaseType::Planar => {
                let [x, y, z, w] = quat;
                let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
                self.q[..3].copy_from_slice(&[p.position.x, p.position.y, yaw]);
                self.v[..3].copy_from_slice(&[t.linear.x, t.linear.y, t.angular.z]);
            }
            BaseType::Floating => {
                self.q[..3].copy_from_slice(&[p.position.x, p.position.y, p.position.z]);
                self.q[3..7].copy_from_slice(&quat);
                self.v[..6].copy_from_slice(&[
                    t.linear.x,
                    t.linear.y,
                    t.linear.z,
                    t.angular.x,
                    t.angular.y,
                    t.angular.z,
                ]);
            }
        }
        self.stamp = Some(od.header.stamp);
        Ok(())
    }

    /// Copies what `old` knows into this (a new model of the same robot): the base and every
    /// joint both models have, by name.
    pub fn carry_over(&mut self, old: &StateEstimate) {
        if old.base == self.base {
            let nb = match self.base {
                BaseType::Fixed => (0, 0),
                BaseType::Planar => (3, 3),
                BaseType::Floating => (7, 6),
            };
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
    }
}
