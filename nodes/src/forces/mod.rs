//! `cd_forces`: the constraint forces at a state, on request (`~/get_constraint_forces`).
//!
//! At the latest state (or one the request gives) under the request's joint torques (or the
//! measured efforts, or none) plus the scene's force elements, the core's
//! [`constraint_forces_at`] gives q̈, λ and each constraint's wrench; this module names them
//! for ROS and judges the contacts as a prediction does (slip and lift-off). A state off the
//! constraints (a measured one, never exactly on them) is projected onto them first, as a
//! prediction's start is, and the reply says how far off it was.

pub mod ros;

use constraint_dynamics::applied::constraint_forces_at;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::predict::DriftProjector;
use serde::{Deserialize, Serialize};

use crate::convert::ForcesAt;
use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForcesRequest, GetConstraintForcesResponse,
};
use crate::node::worker::{NodeLogic, Reply};
use crate::params::{KindParams, NodeParams, ParamsError};
use crate::robot::{Robot, request};
use crate::ros::logging::NodeLog;

/// The forces node has only the common parameters.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ForcesParams {}

impl KindParams for ForcesParams {
    const DYNAMIC: &'static [&'static str] = &["slip."];

    fn validate(&self) -> Result<(), ParamsError> {
        Ok(())
    }
}

/// What the forces node reacts to.
pub enum ForcesInput {
    /// `~/get_constraint_forces`.
    Get(
        GetConstraintForcesRequest,
        Reply<GetConstraintForcesResponse>,
    ),
}

/// The forces node's logic: a robot and its force elements.
pub struct ForcesNode {
    robot: Robot,
    elements: ForceElements,
    params: NodeParams<ForcesParams>,
}

impl NodeLogic for ForcesNode {
    type Params = ForcesParams;
    type Input = ForcesInput;
    type Output = ();

    fn new(
        robot: Robot,
        params: NodeParams<ForcesParams>,
        _log: NodeLog,
    ) -> Result<Self, NodeError> {
        let elements = ForceElements::new(robot.model(), &robot.scene().file.forces)
            .map_err(NodeError::core("force elements"))?;
        Ok(ForcesNode {
            robot,
            elements,
            params,
        })
    }
    fn robot(&self) -> &Robot {
        &self.robot
    }
    fn robot_mut(&mut self) -> &mut Robot {
        &mut self.robot
    }
    fn params(&self) -> &NodeParams<ForcesParams> {
        &self.params
    }
    fn set_params(&mut self, params: NodeParams<ForcesParams>) {
        self.params = params;
    }
    fn handle(&mut self, input: ForcesInput, now: Time, _out: &mut dyn FnMut(())) {
        let ForcesInput::Get(req, reply) = input;
        let _ = reply.try_send(self.get_constraint_forces(&req, now));
    }
}

impl ForcesNode {
    /// `~/get_constraint_forces`: a failure is `success = false` with the reason.
    pub fn get_constraint_forces(
        &mut self,
        req: &GetConstraintForcesRequest,
        now: Time,
    ) -> GetConstraintForcesResponse {
        self.try_get(req, now)
            .unwrap_or_else(|e| GetConstraintForcesResponse {
                success: false,
                message: e.to_string(),
                ..Default::default()
            })
    }

    fn try_get(
        &mut self,
        req: &GetConstraintForcesRequest,
        now: Time,
    ) -> Result<GetConstraintForcesResponse, NodeError> {
        let common = &self.params.common;
        let (mut q, mut v) = self.robot.request_state(
            common,
            req.use_latest_state,
            (&req.q_names, &req.q),
            (&req.v_names, &req.v),
        )?;
        // The latest state is projected already when the parameters say so.
        let off = match req.use_latest_state && common.state.project_to_constraints {
            true => None,
            false => {
                let sys = self.robot.system();
                let off = (DriftProjector::new(sys).project_measured(sys, &mut q, &mut v))
                    .map_err(NodeError::core("state: projection onto the constraints"))?;
                Some(off)
            }
        };
        let model = self.robot.model();
        let tau = if req.tau.is_empty() {
            if req.use_latest_state && common.state.use_measured_effort {
                self.robot.state().effort.clone()
            } else {
                vec![0.0; model.nv]
            }
        } else {
            request::check_values("tau", &req.tau, &model.v_names)?;
            req.tau.clone()
        };
        let at = constraint_forces_at(self.robot.system(), &mut self.elements, (0.0, &q, &v), &tau)
            .map_err(NodeError::core("constraint forces"))?;
        let stamp = match (req.use_latest_state, self.robot.state().stamp) {
            (true, Some(s)) => s,
            _ => now,
        };
        let limits = self.robot.contact_limits(common);
        let states = (self.robot).judge_contacts(&at.lambda, &limits, &self.elements);
        let forces = ForcesAt {
            forces: &at.forces,
            lambda: &at.lambda,
            generalized_force: &at.generalized_force,
            rank_deficiency: at.rank_deficiency,
            contacts: states.as_deref(),
        };
        let msg = self.robot.forces_msg(common, &forces, stamp);
        let slipping: Vec<&str> = msg
            .constraints
            .iter()
            .filter(|c| c.slipping)
            .map(|c| c.name.as_str())
            .collect();
        let mut said = Vec::new();
        if !slipping.is_empty() {
            said.push(format!("slipping: {}", slipping.join(", ")));
        }
        // Said when the projection moved the state (not when its rows were zero to rounding).
        if let Some(o) = off.filter(|o| o.position_correction > 0.0 || o.velocity_correction > 0.0)
        {
            said.push(format!(
                "state projected onto the constraints from |φ| {:.3e} m or rad, |J v| {:.3e} \
                 m/s or rad/s",
                o.position_residual, o.velocity_residual
            ));
        }
        Ok(GetConstraintForcesResponse {
            success: true,
            message: said.join("; "),
            forces: msg,
            qdd: at.qdd,
        })
    }
}

#[cfg(test)]
mod tests;
