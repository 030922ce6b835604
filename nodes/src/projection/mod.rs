//! `cd_projection`: the nearest velocity the constraints allow (`~/project_velocity`), and the
//! same projection as a command filter between a planner and the base controller.
//!
//! The core's [`DynamicProjector`] solves the QP (Clarabel, built once and updated) — with a
//! control period, the cone program of the dynamic projection under the robot's limits
//! ([`EnvelopeModel`]: URDF efforts, friction cones, contacts that push); this module
//! translates the request ([`request`]) and applies the node's limits.

pub mod params;
pub mod request;
pub mod ros;

use constraint_dynamics::System;
use constraint_dynamics::applied::applied_generalized_force;
use constraint_dynamics::envelope::EnvelopeModel;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::projection::{DynamicProjector, ProjectionRequest};

use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::srv::{ProjectVelocityRequest, ProjectVelocityResponse};
use crate::msg::geometry_msgs::Twist;
use crate::msg::std_msgs::Header;
use crate::node::worker::{NodeLogic, Reply};
use crate::params::NodeParams;
use crate::robot::{Robot, request as state_request};
use crate::ros::logging::NodeLog;
pub use params::ProjectionParams;

/// What the projection node reacts to.
pub enum ProjectionInput {
    /// `~/project_velocity`.
    Project(Box<ProjectVelocityRequest>, Reply<ProjectVelocityResponse>),
    /// A command to filter, with the header of a stamped input.
    Filter(Twist, Option<Header>),
}

/// A filtered command (with the input's header when stamped), to publish.
pub struct Filtered(pub Twist, pub Option<Header>);

/// The projection node's logic: a robot, its projector and the robot's limits.
pub struct ProjectionNode {
    robot: Robot,
    projector: DynamicProjector,
    /// The limits of a request with a control period, or why the scene has none.
    limits: Result<EnvelopeModel, String>,
    /// The scene's force elements (springs, dampers, URDF damping): they act over the period.
    elements: ForceElements,
    /// Their generalized force at the request's state, and nv zeros (scratch, nv).
    applied: Vec<f64>,
    zero: Vec<f64>,
    params: NodeParams<ProjectionParams>,
    log: NodeLog,
}

impl NodeLogic for ProjectionNode {
    type Params = ProjectionParams;
    type Input = ProjectionInput;
    type Output = Filtered;

    fn new(
        mut robot: Robot,
        params: NodeParams<ProjectionParams>,
        log: NodeLog,
    ) -> Result<Self, NodeError> {
        let sys = System::from_scene(&robot.scene().rigid_sideways())
            .map_err(NodeError::core("projection"))?;
        // Contacts that declare no μ take `slip.friction_coefficient`, as in the predictor's
        // envelope (read at start; the projection's limits are built once).
        let mu = params.common.slip.friction_coefficient;
        let limits = EnvelopeModel::from_scene(robot.scene(), &sys)
            .map(|em| em.assume_friction(mu))
            .map_err(|e| e.to_string());
        let elements = ForceElements::new(sys.model(), &robot.scene().file.forces)
            .map_err(NodeError::core("projection"))?;
        let sys = robot.kinematic_system();
        let projector = DynamicProjector::new(sys.model(), sys.constraints());
        let nv = sys.model().nv;
        Ok(ProjectionNode {
            robot,
            projector,
            limits,
            elements,
            applied: vec![0.0; nv],
            zero: vec![0.0; nv],
            params,
            log,
        })
    }
    fn robot(&self) -> &Robot {
        &self.robot
    }
    fn robot_mut(&mut self) -> &mut Robot {
        &mut self.robot
    }
    fn params(&self) -> &NodeParams<ProjectionParams> {
        &self.params
    }
    fn set_params(&mut self, params: NodeParams<ProjectionParams>) {
        self.params = params;
    }
    fn handle(&mut self, input: ProjectionInput, _now: Time, out: &mut dyn FnMut(Filtered)) {
        match input {
            ProjectionInput::Project(req, reply) => {
                let _ = reply.try_send(self.project_velocity(&req));
            }
            ProjectionInput::Filter(t, header) => {
                let filtered = match self.filter_command(&t) {
                    Ok((out, resp)) => {
                        if !resp.success {
                            self.log.warn(&format!(
                                "filter: command ({}, {}, {}) is infeasible, sending zero: {}",
                                t.linear.x, t.linear.y, t.angular.z, resp.message
                            ));
                        }
                        out
                    }
                    Err(e) => {
                        self.log
                            .warn(&format!("filter: command refused, sending zero: {e}"));
                        Twist::default()
                    }
                };
                out(Filtered(filtered, header));
            }
        }
    }
}

impl ProjectionNode {
    /// `~/project_velocity`: a refused request is `success = false`, status `error`.
    pub fn project_velocity(&mut self, req: &ProjectVelocityRequest) -> ProjectVelocityResponse {
        self.try_project_velocity(req)
            .unwrap_or_else(|e| ProjectVelocityResponse {
                success: false,
                status: "error".into(),
                message: e.to_string(),
                ..Default::default()
            })
    }

    fn try_project_velocity(
        &mut self,
        req: &ProjectVelocityRequest,
    ) -> Result<ProjectVelocityResponse, NodeError> {
        let limits = &self.params.node.acceleration_limits;
        let pr = request::projection_request(self.robot.model(), limits, req)?;
        let (q, v) = if req.use_latest_state {
            self.robot
                .latest_state(self.params.common.state.project_to_constraints)?
        } else {
            let model = self.robot.model();
            let state = self.robot.state();
            let mut q = state_request::assemble("q", &[], &req.q, &state.q, &model.q_names, false)?;
            model.normalize(&mut q);
            // The velocity the period starts from: the request's, else the latest measured.
            let v = if req.v_current.is_empty() {
                state.v.clone()
            } else {
                state_request::check_values("v_current", &req.v_current, &model.v_names)?;
                req.v_current.clone()
            };
            (q, v)
        };
        self.project(&q, &v, &pr)
    }

    /// Project at (q, v): the kinematic projection, or with a period the dynamic one under the
    /// robot's limits and the scene's force elements at (q, v).
    fn project(
        &mut self,
        q: &[f64],
        v: &[f64],
        pr: &ProjectionRequest,
    ) -> Result<ProjectVelocityResponse, NodeError> {
        let limits = match (&self.limits, pr.period > 0.0) {
            (_, false) => None,
            (Ok(em), true) => Some(em),
            (Err(why), true) => {
                return Err(NodeError::request(
                    "period",
                    format!("this scene's limits are unavailable: {why}"),
                ));
            }
        };
        let sys = self.robot.kinematic_system();
        if limits.is_some() {
            applied_generalized_force(
                sys,
                &mut self.elements,
                (0.0, q, v),
                &self.zero,
                &mut self.applied,
            );
        }
        let out = self
            .projector
            .project_request(sys, limits, q, v, &self.applied, pr)
            .map_err(NodeError::core("projection"))?;
        Ok(request::response(&out))
    }

    /// The filter: a command twist in, the projected twist out (zero twist when infeasible).
    pub fn filter_command(
        &mut self,
        cmd: &Twist,
    ) -> Result<(Twist, ProjectVelocityResponse), NodeError> {
        let f = &self.params.node.filter;
        let req = ProjectVelocityRequest {
            use_latest_state: true,
            use_twist: true,
            base_twist: *cmd,
            accel_limit_dt: f.accel_limit_dt,
            period: f.control_period,
            ..Default::default()
        };
        let mut pr = request::projection_request(
            self.robot.model(),
            &self.params.node.acceleration_limits,
            &req,
        )?;
        pr.velocity_limits = f.velocity_limits;
        let (q, v) = self
            .robot
            .latest_state(self.params.common.state.project_to_constraints)?;
        let resp = self.project(&q, &v, &pr)?;
        let twist = if resp.success {
            resp.base_twist
        } else {
            Twist::default()
        };
        Ok((twist, resp))
    }
}

#[cfg(test)]
mod tests;
