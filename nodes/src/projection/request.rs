//! A `ProjectVelocity` request as the core's [`ProjectionRequest`], and the core's projection
//! named back into the response.

use std::collections::BTreeMap;

use constraint_dynamics::Model;
use constraint_dynamics::model::BaseTwist;
use constraint_dynamics::projection::{
    AccelLimitRequest, PerCoordinate, Projection, ProjectionRequest, Side, Status,
};
use constraint_dynamics::robot_limits::NamedLimit;

use super::params::AccelerationLimitsParams;
use crate::convert::{base_twist_of, twist_msg};
use crate::error::NodeError;
use crate::msg::constraint_dynamics_msgs::srv::{ProjectVelocityRequest, ProjectVelocityResponse};
use crate::msg::geometry_msgs::Twist;
use crate::robot::request::same_len;

/// The core request for a ROS request (coordinate names are checked by the core).
pub fn projection_request(
    model: &Model,
    limits: &AccelerationLimitsParams,
    req: &ProjectVelocityRequest,
) -> Result<ProjectionRequest, NodeError> {
    let mut pr = ProjectionRequest::default();
    if req.use_twist {
        let twist = base_twist_of(&req.base_twist);
        pr.base_twist = Some(
            model
                .base_velocity(&twist)
                .map_err(|e| NodeError::request("base_twist", e.to_string()))?,
        );
        same_len(
            "joint_names",
            &req.joint_names,
            "joint_velocities",
            req.joint_velocities.len(),
        )?;
        for (n, x) in req.joint_names.iter().zip(&req.joint_velocities) {
            pr.joints.insert(n.clone(), *x);
        }
    } else if req.v_names.is_empty() {
        if req.v_des.is_empty() {
            return Err(NodeError::request(
                "v_des",
                "no desired velocity: give v_des (all nv values, or with v_names), \
                 or set use_twist with base_twist",
            ));
        }
        pr.v_des = Some(req.v_des.clone());
    } else {
        same_len("v_names", &req.v_names, "v_des", req.v_des.len())?;
        for (n, x) in req.v_names.iter().zip(&req.v_des) {
            if pr.joints.insert(n.clone(), *x).is_some() {
                return Err(NodeError::request(
                    "v_names",
                    format!("'{n}' is given twice"),
                ));
            }
        }
    }
    same_len("bound_names", &req.bound_names, "lower", req.lower.len())?;
    same_len("bound_names", &req.bound_names, "upper", req.upper.len())?;
    if !req.bound_names.is_empty() {
        let (mut lo, mut hi) = (BTreeMap::new(), BTreeMap::new());
        for (k, n) in req.bound_names.iter().enumerate() {
            let (l, u) = (req.lower[k], req.upper[k]);
            if l.is_nan() || u.is_nan() {
                return Err(NodeError::request(
                    format!("bounds of '{n}'"),
                    "NaN (use ±inf for no bound)",
                ));
            }
            lo.insert(n.clone(), l.is_finite().then_some(l));
            hi.insert(n.clone(), u.is_finite().then_some(u));
        }
        pr.lower = Some(PerCoordinate::Named(lo));
        pr.upper = Some(PerCoordinate::Named(hi));
    }
    let dt = req.accel_limit_dt;
    if dt.is_nan() || dt < 0.0 || dt.is_infinite() {
        return Err(NodeError::request(
            "accel_limit_dt",
            format!("{dt} must be finite and ≥ 0 (0: no acceleration limit)"),
        ));
    }
    if dt > 0.0 {
        pr.accel_limit = Some(AccelLimitRequest {
            dt,
            a_max: PerCoordinate::Named(
                limits
                    .names
                    .iter()
                    .cloned()
                    .zip(limits.values.iter().map(|x| Some(*x)))
                    .collect(),
            ),
            v_current: None,
        });
    }
    let period = req.period;
    if !period.is_finite() || period < 0.0 {
        return Err(NodeError::request(
            "period",
            format!("{period} must be finite and ≥ 0 (0: the kinematic projection)"),
        ));
    }
    pr.period = period;
    Ok(pr)
}

/// The response for the core's projection.
pub fn response(out: &Projection) -> ProjectVelocityResponse {
    let optimal = out.status == Status::Optimal;
    let dynamics = out.dynamics.as_ref();
    let base_twist = match out.base_twist.as_deref() {
        Some(&[vx, vy, wz]) => twist_msg(&BaseTwist {
            linear: [vx, vy, 0.0],
            angular: [0.0, 0.0, wz],
        }),
        Some(&[vx, vy, vz, wx, wy, wz]) => twist_msg(&BaseTwist {
            linear: [vx, vy, vz],
            angular: [wx, wy, wz],
        }),
        _ => Twist::default(),
    };
    ProjectVelocityResponse {
        success: optimal,
        message: out.message.clone(),
        status: if optimal { "optimal" } else { "infeasible" }.into(),
        v_names: out.v_names.clone(),
        v: out.v.clone().unwrap_or_default(),
        base_twist,
        joint_names: out.joint_names.clone(),
        joint_velocities: out.joint_velocities.clone().unwrap_or_default(),
        constraint_names: out.constraint_rows.clone(),
        impulses: out.impulses.clone().unwrap_or_default(),
        active_bounds: out
            .active_bounds
            .iter()
            .map(|b| {
                let side = match b.side {
                    Side::Lower => ">=",
                    Side::Upper => "<=",
                };
                format!("{} {side} {} ({})", b.coordinate, b.value, b.source.label())
            })
            .collect(),
        conflicting: out.conflicts.iter().map(|c| c.label.clone()).collect(),
        binding_kinds: named(dynamics.map(|d| &d.binding), |l| l.kind.to_string()),
        binding_names: named(dynamics.map(|d| &d.binding), |l| l.name.clone()),
        unchecked_kinds: named(dynamics.map(|d| &d.unchecked), |l| l.kind.to_string()),
        unchecked_names: named(dynamics.map(|d| &d.unchecked), |l| l.name.clone()),
    }
}

/// One field of each named limit (none without a period).
fn named(limits: Option<&Vec<NamedLimit>>, field: impl Fn(&NamedLimit) -> String) -> Vec<String> {
    limits.map_or_else(Vec::new, |l| l.iter().map(field).collect())
}
