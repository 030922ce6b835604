//! The domain side of a node: a scene's model with its constraints, predictor and velocity
//! projector, the latest state, and what each request or tick computes. No ROS handles here:
//! requests and results are the message structs of [`crate::msg`], which are plain data.
//!
//! Every computation is the core library's (`System::forward_dynamics` + `constraint_forces`,
//! `Predictor::predict`, `projection::project_system`); the engine only maps names, checks
//! requests and fills messages. A request it cannot serve gets `success = false` and a
//! message that says why; nothing here panics on input (the worker also catches panics).

use std::time::Instant;

use constraint_dynamics::actuators::Command;
use constraint_dynamics::algorithm::forward_kinematics;
use constraint_dynamics::constraints::ConstraintForce as CoreForce;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::predict::{Predictor, Trajectory, drift};
use constraint_dynamics::projection::{
    AccelLimitRequest, PerCoordinate, ProjectionRequest, Status, VelocityProjector, project_system,
};
use constraint_dynamics::{BaseType, Scene, System};

use crate::convert::{
    ForcesContext, SlipRule, base_pose, base_twist, constraint_forces_msg, diagonal_covariance,
    frame_origins, path_poses, time_plus,
};
use crate::logging::NodeLog;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::ConstraintForces;
use crate::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForcesRequest, GetConstraintForcesResponse, PredictRequest, PredictResponse,
    ProjectVelocityRequest, ProjectVelocityResponse,
};
use crate::msg::geometry_msgs::{Twist, Vector3};
use crate::msg::nav_msgs::{Odometry, Path};
use crate::msg::sensor_msgs::JointState;
use crate::msg::std_msgs::Header;
use crate::params::{Fallback, NodeParams};
use crate::state::{JointStateReport, StateEstimate};

/// A twist with lateral components below this is taken as a (v, ω) command [m/s, rad/s].
const TWIST_TOL: f64 = 1e-9;

/// What one periodic prediction publishes.
#[derive(Clone, Debug)]
pub struct PeriodicOutput {
    /// The base at the horizon (stamp = start + horizon).
    pub odom: Odometry,
    /// The base along the prediction.
    pub path: Path,
    /// Constraint forces at the start state under the commanded actuator torques.
    pub forces: ConstraintForces,
    /// Time spent computing [s].
    pub compute_s: f64,
}

/// Constraint forces at one state: q̈ (nv), the core's forces, Jᵀλ (nv), rank deficiency.
struct ForcesAt {
    qdd: Vec<f64>,
    forces: Vec<CoreForce>,
    generalized_force: Vec<f64>,
    rank_deficiency: usize,
}

/// A scene-bound engine. See the module documentation.
pub struct Engine {
    params: NodeParams,
    scene: Scene,
    /// Forces and projection (multiplier formulation, so λ is always there).
    sys: System,
    predictor: Predictor,
    projector: VelocityProjector,
    state: StateEstimate,
    /// Names of the joints with position controllers in the scene, and their q index.
    held_joints: Vec<(String, usize)>,
    has_diff_drive: bool,
    n_rolling: usize,
    base_frame: String,
    log: NodeLog,
    /// Slip flags of the last periodic prediction (to log transitions).
    last_slip: Vec<bool>,
    last_slip_log: Option<Instant>,
}

impl Engine {
    /// Loads the scene file named in the parameters (already resolved to a path).
    pub fn load(params: NodeParams, log: NodeLog) -> Result<Self, String> {
        let path = params.common().model.scene_file.clone();
        let scene = Scene::load(&path).map_err(|e| format!("scene {path}: {e}"))?;
        Self::from_scene(scene, params, log)
    }

    /// Builds everything from a loaded scene.
    pub fn from_scene(scene: Scene, params: NodeParams, log: NodeLog) -> Result<Self, String> {
        let e = |what: &str, err: constraint_dynamics::Error| format!("{what}: {err}");
        let mut sys = System::from_scene(&scene).map_err(|x| e("constraints", x))?;
        sys.formulation = Formulation::Multipliers;
        let predictor = Predictor::from_scene(&scene).map_err(|x| e("predictor", x))?;
        let projector = VelocityProjector::new(&sys.model, &sys.constraints);
        let state = StateEstimate::new(&scene.model, &scene.q0, &scene.v0);
        let held_joints = scene
            .file
            .actuators
            .position
            .iter()
            .filter_map(|c| state.joint(&c.joint).map(|(iq, _)| (c.joint.clone(), iq)))
            .collect();
        let has_diff_drive = scene.file.actuators.diff_drive.is_some();
        let n_rolling = sys
            .constraints
            .items
            .iter()
            .filter(|c| c.kind() == "rolling")
            .count();
        let base_frame = match params.common().frames.base_frame.as_str() {
            "" => scene
                .model
                .bodies
                .get(1)
                .map(|b| b.name.clone())
                .unwrap_or_else(|| "base_link".into()),
            f => f.to_string(),
        };
        let nc = sys.constraints.items.len();
        Ok(Engine {
            params,
            scene,
            sys,
            predictor,
            projector,
            state,
            held_joints,
            has_diff_drive,
            n_rolling,
            base_frame,
            log,
            last_slip: vec![false; nc],
            last_slip_log: None,
        })
    }

    /// A new engine for the URDF of a `/robot_description` message, with this engine's scene
    /// settings and state (carried over by name).
    pub fn with_urdf(&self, urdf: &str) -> Result<Engine, String> {
        if urdf.trim().is_empty() {
            return Err("the URDF is empty".into());
        }
        let scene = Scene::from_parts(
            &self.scene.path,
            self.scene.file.clone(),
            urdf,
            "robot_description",
        )
        .map_err(|e| e.to_string())?;
        let mut next = Engine::from_scene(scene, self.params.clone(), self.log.clone())?;
        next.state.carry_over(&self.state);
        Ok(next)
    }

    /// A fresh engine with the same scene and parameters (after a caught panic).
    pub fn rebuilt(&self) -> Result<Engine, String> {
        let mut next =
            Engine::from_scene(self.scene.clone(), self.params.clone(), self.log.clone())?;
        next.state.carry_over(&self.state);
        Ok(next)
    }

    pub fn params(&self) -> &NodeParams {
        &self.params
    }

    /// Replaces the parameters (run-time changes of the dynamic ones).
    pub fn set_params(&mut self, params: NodeParams) {
        self.params = params;
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn state(&self) -> &StateEstimate {
        &self.state
    }

    /// The child frame of the predicted odometry.
    pub fn base_frame(&self) -> &str {
        &self.base_frame
    }

    pub fn apply_joint_state(&mut self, js: &JointState) -> Result<JointStateReport, String> {
        self.state.apply_joint_state(js)
    }

    pub fn apply_odometry(&mut self, od: &Odometry) -> Result<(), String> {
        self.state.apply_odometry(od)
    }

    fn slip_rule(&self) -> SlipRule {
        SlipRule::new(self.params.common().slip, &self.scene.model, self.n_rolling)
    }

    /// The latest state, projected onto the constraints when `state.project_to_constraints`.
    pub fn latest_state(&mut self) -> Result<(Vec<f64>, Vec<f64>), String> {
        let (mut q, mut v) = (self.state.q.clone(), self.state.v.clone());
        self.scene.model.normalize(&mut q);
        if self.params.common().state.project_to_constraints {
            drift::project(&mut self.sys, &mut q, &mut v, true)
                .map_err(|e| format!("latest state: projection onto the constraints: {e}"))?;
        }
        Ok((q, v))
    }

    // ---------------------------------------------------------------------------------------
    // Commands.

    /// The core command for a base (v, ω), holding the position-controlled joints at `q0`.
    fn command(&self, base: Option<[f64; 2]>, q0: &[f64]) -> Command {
        let mut cmd = Command {
            base_twist: if self.has_diff_drive { base } else { None },
            ..Default::default()
        };
        if self.params.command().hold_joints {
            for (name, iq) in &self.held_joints {
                cmd.joint_position.insert(name.clone(), q0[*iq]);
            }
        }
        cmd
    }

    /// The base (v, ω) used without a fresh command.
    fn fallback_twist(&self, v0: &[f64]) -> Option<[f64; 2]> {
        match self.params.command().fallback() {
            Ok(Fallback::Hold) => Some(match self.scene.model.base {
                BaseType::Planar => [v0[0], v0[2]],
                BaseType::Floating => [v0[0], v0[5]],
                BaseType::Fixed => [0.0, 0.0],
            }),
            Ok(Fallback::Coast) => None,
            _ => Some([0.0, 0.0]),
        }
    }

    /// (v, ω) of a twist command, refusing what a differential drive cannot do.
    pub fn twist_command(&self, t: &Twist, what: &str) -> Result<[f64; 2], String> {
        let all = [
            t.linear.x,
            t.linear.y,
            t.linear.z,
            t.angular.x,
            t.angular.y,
            t.angular.z,
        ];
        if let Some(x) = all.iter().find(|x| !x.is_finite()) {
            return Err(format!("{what}: twist has a non-finite value ({x})"));
        }
        let lateral = [t.linear.y, t.linear.z, t.angular.x, t.angular.y];
        if lateral.iter().any(|x| x.abs() > TWIST_TOL) {
            return Err(format!(
                "{what}: a differential drive follows linear.x and angular.z only \
                 (linear.y, linear.z, angular.x, angular.y = {:?})",
                lateral
            ));
        }
        if !self.has_diff_drive {
            return Err(format!(
                "{what}: the scene {} has no actuators.diff_drive, so it cannot follow base twists",
                self.scene.path.display()
            ));
        }
        Ok([t.linear.x, t.angular.z])
    }

    // ---------------------------------------------------------------------------------------
    // Forces at a state.

    /// Constraint forces at (q, v) under actuator torques `tau_act` plus the scene's force
    /// elements: (q̈, core forces, Jᵀλ, rank deficiency).
    fn forces_at(&mut self, q: &[f64], v: &[f64], tau_act: &[f64]) -> Result<ForcesAt, String> {
        let nv = self.scene.model.nv;
        let mut tau = tau_act.to_vec();
        if !self.predictor.forces.is_empty() {
            let zero = vec![0.0; nv];
            forward_kinematics(&self.sys.model, &mut self.sys.data, q, v, &zero);
            self.predictor.forces.add_generalized_force(
                &self.sys.model,
                &self.sys.data,
                0.0,
                q,
                v,
                &mut tau,
            );
        }
        let qdd: Vec<f64> = self
            .sys
            .forward_dynamics(q, v, &tau, true)
            .map_err(|e| e.to_string())?
            .iter()
            .copied()
            .collect();
        Ok(ForcesAt {
            qdd,
            forces: self.sys.constraint_forces(),
            generalized_force: self.sys.kkt.generalized_force.iter().copied().collect(),
            rank_deficiency: self.sys.kkt.rank_deficiency,
        })
    }

    fn forces_msg(
        &mut self,
        q: &[f64],
        forces: &[CoreForce],
        gf: &[f64],
        rank_deficiency: usize,
        stamp: Time,
    ) -> ConstraintForces {
        let origins = frame_origins(&mut self.sys, q, forces);
        let slip = self.slip_rule();
        let ctx = ForcesContext {
            stamp,
            world_frame: &self.params.common().frames.odom_frame,
            v_names: &self.scene.model.v_names,
            generalized_force: gf,
            rank_deficiency,
            slip,
        };
        constraint_forces_msg(forces, &origins, &ctx)
    }

    /// `~/get_constraint_forces`.
    pub fn get_constraint_forces(
        &mut self,
        req: &GetConstraintForcesRequest,
        now: Time,
    ) -> GetConstraintForcesResponse {
        match self.try_get_constraint_forces(req, now) {
            Ok(r) => r,
            Err(message) => GetConstraintForcesResponse {
                success: false,
                message,
                ..Default::default()
            },
        }
    }

    fn try_get_constraint_forces(
        &mut self,
        req: &GetConstraintForcesRequest,
        now: Time,
    ) -> Result<GetConstraintForcesResponse, String> {
        let (nq, nv) = (self.scene.model.nq, self.scene.model.nv);
        let (q, v) = if req.use_latest_state {
            self.latest_state()?
        } else {
            let model = &self.scene.model;
            let q = assemble(
                "q",
                &req.q_names,
                &req.q,
                &self.state.q,
                &model.q_names,
                false,
            )?;
            let v = assemble(
                "v",
                &req.v_names,
                &req.v,
                &self.state.v,
                &model.v_names,
                true,
            )?;
            let mut q = q;
            model.normalize(&mut q);
            (q, v)
        };
        let model = &self.scene.model;
        let tau = if req.tau.is_empty() {
            if req.use_latest_state && self.params.common().state.use_measured_effort {
                self.state.effort.clone()
            } else {
                vec![0.0; nv]
            }
        } else {
            check_values("tau", &req.tau, &model.v_names)?;
            req.tau.clone()
        };
        debug_assert_eq!((q.len(), v.len()), (nq, nv));
        let ForcesAt {
            qdd,
            forces,
            generalized_force: gf,
            rank_deficiency: rank,
        } = self.forces_at(&q, &v, &tau)?;
        let stamp = if req.use_latest_state {
            self.state.stamp.unwrap_or(now)
        } else {
            now
        };
        let msg = self.forces_msg(&q, &forces, &gf, rank, stamp);
        let slipping: Vec<&str> = msg
            .constraints
            .iter()
            .filter(|c| c.slipping)
            .map(|c| c.name.as_str())
            .collect();
        Ok(GetConstraintForcesResponse {
            success: true,
            message: if slipping.is_empty() {
                String::new()
            } else {
                format!("slipping: {}", slipping.join(", "))
            },
            forces: msg,
            qdd,
        })
    }

    // ---------------------------------------------------------------------------------------
    // Velocity projection.

    /// The core projection request for a ROS request (names checked by the core).
    fn projection_request(
        &self,
        req: &ProjectVelocityRequest,
    ) -> Result<ProjectionRequest, String> {
        let model = &self.scene.model;
        let mut pr = ProjectionRequest::default();
        if req.use_twist {
            let t = &req.base_twist;
            pr.base_twist = Some(match model.base {
                BaseType::Planar => {
                    if [t.linear.z, t.angular.x, t.angular.y]
                        .iter()
                        .any(|x| x.abs() > TWIST_TOL)
                    {
                        return Err(format!(
                            "base_twist: a planar base cannot move along z or roll/pitch \
                             (linear.z, angular.x, angular.y = {}, {}, {})",
                            t.linear.z, t.angular.x, t.angular.y
                        ));
                    }
                    vec![t.linear.x, t.linear.y, t.angular.z]
                }
                BaseType::Floating => vec![
                    t.linear.x,
                    t.linear.y,
                    t.linear.z,
                    t.angular.x,
                    t.angular.y,
                    t.angular.z,
                ],
                BaseType::Fixed => {
                    return Err("use_twist: the model has a fixed base".into());
                }
            });
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
                return Err(
                    "no desired velocity: give v_des (all nv values, or with v_names), \
                     or set use_twist with base_twist"
                        .into(),
                );
            }
            pr.v_des = Some(req.v_des.clone());
        } else {
            same_len("v_names", &req.v_names, "v_des", req.v_des.len())?;
            for (n, x) in req.v_names.iter().zip(&req.v_des) {
                if pr.joints.insert(n.clone(), *x).is_some() {
                    return Err(format!("v_names: '{n}' is given twice"));
                }
            }
        }
        same_len("bound_names", &req.bound_names, "lower", req.lower.len())?;
        same_len("bound_names", &req.bound_names, "upper", req.upper.len())?;
        if !req.bound_names.is_empty() {
            let mut lo = std::collections::BTreeMap::new();
            let mut hi = std::collections::BTreeMap::new();
            for (k, n) in req.bound_names.iter().enumerate() {
                let (l, u) = (req.lower[k], req.upper[k]);
                if l.is_nan() || u.is_nan() {
                    return Err(format!("bounds of '{n}': NaN (use ±inf for no bound)"));
                }
                lo.insert(n.clone(), l.is_finite().then_some(l));
                hi.insert(n.clone(), u.is_finite().then_some(u));
            }
            pr.lower = Some(PerCoordinate::Named(lo));
            pr.upper = Some(PerCoordinate::Named(hi));
        }
        if req.accel_limit_dt.is_nan() || req.accel_limit_dt < 0.0 {
            return Err(format!(
                "accel_limit_dt = {} must be ≥ 0 (0: no acceleration limit)",
                req.accel_limit_dt
            ));
        }
        if req.accel_limit_dt > 0.0 {
            pr.accel_limit = Some(self.accel_limit(req.accel_limit_dt)?);
        }
        Ok(pr)
    }

    fn accel_limit(&self, dt: f64) -> Result<AccelLimitRequest, String> {
        let NodeParams::Projection(p) = &self.params else {
            return Err("acceleration limits are a parameter of the projection node".into());
        };
        if !dt.is_finite() {
            return Err(format!("accel_limit_dt = {dt} must be finite"));
        }
        let a = &p.acceleration_limits;
        Ok(AccelLimitRequest {
            dt,
            a_max: PerCoordinate::Named(
                a.names
                    .iter()
                    .cloned()
                    .zip(a.values.iter().map(|x| Some(*x)))
                    .collect(),
            ),
            v_current: None,
        })
    }

    /// `~/project_velocity`.
    pub fn project_velocity(&mut self, req: &ProjectVelocityRequest) -> ProjectVelocityResponse {
        match self.try_project_velocity(req) {
            Ok(r) => r,
            Err(message) => ProjectVelocityResponse {
                success: false,
                status: "error".into(),
                message,
                ..Default::default()
            },
        }
    }

    fn try_project_velocity(
        &mut self,
        req: &ProjectVelocityRequest,
    ) -> Result<ProjectVelocityResponse, String> {
        let pr = self.projection_request(req)?;
        let (q, v) = if req.use_latest_state {
            self.latest_state()?
        } else {
            let model = &self.scene.model;
            let mut q = assemble("q", &[], &req.q, &self.state.q, &model.q_names, false)?;
            model.normalize(&mut q);
            (q, self.state.v.clone())
        };
        self.project(&q, &v, &pr)
    }

    /// Runs the core projection and names the result for ROS.
    pub fn project(
        &mut self,
        q: &[f64],
        v_current: &[f64],
        pr: &ProjectionRequest,
    ) -> Result<ProjectVelocityResponse, String> {
        let out = project_system(&mut self.projector, &mut self.sys, q, v_current, pr)
            .map_err(|e| e.to_string())?;
        let optimal = out.status == Status::Optimal;
        let base_twist = match &out.base_twist {
            Some(b) if b.len() == 3 => Twist {
                linear: Vector3 {
                    x: b[0],
                    y: b[1],
                    z: 0.0,
                },
                angular: Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: b[2],
                },
            },
            Some(b) if b.len() == 6 => Twist {
                linear: Vector3 {
                    x: b[0],
                    y: b[1],
                    z: b[2],
                },
                angular: Vector3 {
                    x: b[3],
                    y: b[4],
                    z: b[5],
                },
            },
            _ => Twist::default(),
        };
        Ok(ProjectVelocityResponse {
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
                    format!(
                        "{} {} {} ({})",
                        b.coordinate,
                        match b.side {
                            constraint_dynamics::projection::Side::Lower => ">=",
                            constraint_dynamics::projection::Side::Upper => "<=",
                        },
                        b.value,
                        b.source.label()
                    )
                })
                .collect(),
            conflicting: out.conflicts.iter().map(|c| c.label.clone()).collect(),
        })
    }

    /// The filter: a command twist in, the projected twist out (zero twist when infeasible).
    pub fn filter_command(
        &mut self,
        cmd: &Twist,
    ) -> Result<(Twist, ProjectVelocityResponse), String> {
        let NodeParams::Projection(p) = &self.params else {
            return Err("the filter belongs to the projection node".into());
        };
        let (velocity_limits, dt) = (p.filter.velocity_limits, p.filter.accel_limit_dt);
        let req = ProjectVelocityRequest {
            use_latest_state: true,
            use_twist: true,
            base_twist: *cmd,
            accel_limit_dt: dt,
            ..Default::default()
        };
        let mut pr = self.projection_request(&req)?;
        pr.velocity_limits = velocity_limits;
        let (q, v) = self.latest_state()?;
        let resp = self.project(&q, &v, &pr)?;
        let out = if resp.success {
            resp.base_twist
        } else {
            Twist::default()
        };
        Ok((out, resp))
    }

    // ---------------------------------------------------------------------------------------
    // Prediction.

    /// Horizon of the periodic prediction [s].
    fn periodic_horizon(&self) -> f64 {
        match &self.params {
            NodeParams::Predictor(p) if p.horizon > 0.0 => p.horizon,
            _ => self.scene.file.integration.horizon,
        }
    }

    /// One periodic prediction from the latest state under `command` (v, ω) — `None` = no
    /// fresh command (the fallback applies).
    pub fn periodic(
        &mut self,
        now: Time,
        command: Option<[f64; 2]>,
    ) -> Result<PeriodicOutput, String> {
        let t0 = Instant::now();
        let (q, v) = self.latest_state()?;
        let base = command.or_else(|| self.fallback_twist(&v));
        let cmd = self.command(base, &q);
        let horizon = self.periodic_horizon();
        if !horizon.is_finite() || horizon <= 0.0 {
            return Err(format!(
                "the prediction horizon is {horizon} s: set `horizon` or the scene's integration.horizon"
            ));
        }
        self.predictor.want_forces = false;
        let traj = self
            .predictor
            .predict(&q, &v, &[(0.0, cmd.clone())], horizon)
            .map_err(|e| format!("prediction: {e}"))?;
        let odom = self.odometry_at_horizon(&traj, now)?;
        let path = self.path(&traj, now);
        // Forces at the start state, under the torques the controllers apply in the first tick.
        let tau = self.first_tick_torque(&cmd, &q, &v, horizon);
        let f = self.forces_at(&q, &v, &tau)?;
        let forces = self.forces_msg(&q, &f.forces, &f.generalized_force, f.rank_deficiency, now);
        self.log_slip(&forces);
        Ok(PeriodicOutput {
            odom,
            path,
            forces,
            compute_s: t0.elapsed().as_secs_f64(),
        })
    }

    /// The actuator torque of the predictor's first control tick (integrators reset).
    pub fn first_tick_torque(&self, cmd: &Command, q: &[f64], v: &[f64], horizon: f64) -> Vec<f64> {
        let mut tau = vec![0.0; self.scene.model.nv];
        let mut act = self.predictor.actuators.clone();
        if act.is_empty() {
            return tau;
        }
        act.reset();
        let s = &self.predictor.settings;
        let dt = act.control_period.min(s.sample_period).min(horizon);
        act.update(cmd, q, v, dt, &mut tau);
        tau
    }

    /// The predicted base poses as a `nav_msgs/Path` in the odom frame, stamped from `now`.
    fn path(&self, traj: &Trajectory, now: Time) -> Path {
        let frame = self.params.common().frames.odom_frame.clone();
        Path {
            header: Header {
                stamp: now,
                frame_id: frame.clone(),
            },
            poses: path_poses(
                &self.scene.model,
                traj.samples.iter().map(|s| (s.t, s.q.as_slice())),
                now,
                &frame,
            ),
        }
    }

    fn odometry_at_horizon(&self, traj: &Trajectory, start: Time) -> Result<Odometry, String> {
        let model = &self.scene.model;
        let last = traj.samples.last().ok_or("the prediction has no samples")?;
        let err = if last.error_estimate.is_finite() {
            last.error_estimate
        } else {
            0.0
        } + last.position_residual;
        let default = crate::params::CovarianceParams::default();
        let c = match &self.params {
            NodeParams::Predictor(p) => &p.covariance,
            _ => &default,
        };
        let sp = err.hypot(c.position_floor);
        let so = err.hypot(c.orientation_floor);
        let st = c.twist_floor;
        let mut odom = Odometry {
            header: Header {
                stamp: time_plus(start, last.t),
                frame_id: self.params.common().frames.odom_frame.clone(),
            },
            child_frame_id: self.base_frame.clone(),
            ..Default::default()
        };
        odom.pose.pose = base_pose(model, &last.q);
        odom.pose.covariance = diagonal_covariance([sp, sp, sp, so, so, so]);
        odom.twist.twist = base_twist(model, &last.v);
        odom.twist.covariance = diagonal_covariance([st; 6]);
        Ok(odom)
    }

    fn log_slip(&mut self, forces: &ConstraintForces) {
        let now = Instant::now();
        let throttled = self
            .last_slip_log
            .is_some_and(|t| now.duration_since(t).as_secs_f64() < 1.0);
        let mu = self.params.common().slip.friction_coefficient;
        for (k, c) in forces.constraints.iter().enumerate() {
            let was = self.last_slip.get(k).copied().unwrap_or(false);
            if c.slipping && (!was || !throttled) {
                self.log.warn(&format!(
                    "slip: rolling contact '{}' needs a tangential force of {:.3} N > μ·N = {} × {:.3} N",
                    c.name, c.tangential_force, mu, c.normal_force
                ));
                self.last_slip_log = Some(now);
            } else if !c.slipping && was {
                self.log
                    .info(&format!("slip: rolling contact '{}' grips again", c.name));
            }
            if let Some(s) = self.last_slip.get_mut(k) {
                *s = c.slipping;
            }
        }
    }

    /// `~/predict`.
    pub fn predict(&mut self, req: &PredictRequest, now: Time) -> PredictResponse {
        match self.try_predict(req, now) {
            Ok(r) => r,
            Err(message) => PredictResponse {
                success: false,
                message,
                ..Default::default()
            },
        }
    }

    fn try_predict(&mut self, req: &PredictRequest, now: Time) -> Result<PredictResponse, String> {
        let (max_horizon, max_commands) = match &self.params {
            NodeParams::Prediction(p) => (p.max_horizon, p.max_commands as usize),
            _ => (f64::INFINITY, usize::MAX),
        };
        if !(req.horizon.is_finite() && req.horizon > 0.0) {
            return Err(format!(
                "horizon = {} s must be positive and finite",
                req.horizon
            ));
        }
        if req.horizon > max_horizon {
            return Err(format!(
                "horizon = {} s is longer than max_horizon = {max_horizon} s",
                req.horizon
            ));
        }
        if req.commands.len() > max_commands {
            return Err(format!(
                "{} commands: at most max_commands = {max_commands}",
                req.commands.len()
            ));
        }
        if req.commands.len() > 1 && !(req.command_period.is_finite() && req.command_period > 0.0) {
            return Err(format!(
                "command_period = {} s must be positive with more than one command",
                req.command_period
            ));
        }
        let (q, v) = if req.use_latest_state {
            self.latest_state()?
        } else {
            let model = &self.scene.model;
            let mut q = assemble("q", &[], &req.q, &self.state.q, &model.q_names, false)?;
            let v = assemble("v", &[], &req.v, &self.state.v, &model.v_names, true)?;
            model.normalize(&mut q);
            (q, v)
        };
        let mut commands = Vec::with_capacity(req.commands.len().max(1));
        for (k, t) in req.commands.iter().enumerate() {
            let base = self.twist_command(t, &format!("commands[{k}]"))?;
            commands.push((k as f64 * req.command_period, self.command(Some(base), &q)));
        }
        if commands.is_empty() {
            commands.push((0.0, self.command(self.fallback_twist(&v), &q)));
        }
        self.predictor.want_forces = req.with_forces;
        let traj = self
            .predictor
            .predict(&q, &v, &commands, req.horizon)
            .map_err(|e| format!("prediction: {e}"))?;
        self.predictor.want_forces = false;
        let path = self.path(&traj, now);
        let mut forces = Vec::new();
        if req.with_forces {
            for s in &traj.samples {
                let Some(f) = &s.forces else { continue };
                let gf = self.generalized_force_of(&s.q, &s.v, s.lambda.as_deref());
                let rank = s.rank_deficiency.unwrap_or(0);
                forces.push(self.forces_msg(&s.q, f, &gf, rank, time_plus(now, s.t)));
            }
        }
        let last = traj.samples.last().ok_or("the prediction has no samples")?;
        let estimate = if last.error_estimate.is_finite() {
            last.error_estimate
        } else {
            0.0
        } + last.position_residual;
        Ok(PredictResponse {
            success: true,
            message: format!(
                "{} samples, {} steps in {:.3} ms ({:?})",
                traj.samples.len(),
                traj.steps,
                traj.run_time_s * 1e3,
                traj.method
            ),
            path,
            times: traj.samples.iter().map(|s| s.t).collect(),
            forces,
            position_error_estimate: estimate,
        })
    }

    /// Jᵀλ at (q, v) for multipliers λ (empty when none).
    fn generalized_force_of(&mut self, q: &[f64], v: &[f64], lambda: Option<&[f64]>) -> Vec<f64> {
        let Some(lambda) = lambda else {
            return Vec::new();
        };
        let sys = &mut self.sys;
        sys.constraints
            .evaluate(&sys.model, &mut sys.data, &mut sys.cdata, q, v);
        let j = &sys.cdata.j;
        (0..j.ncols())
            .map(|c| (0..j.nrows()).map(|r| j[(r, c)] * lambda[r]).sum())
            .collect()
    }
}

/// A state vector from a request: positional (`names` empty: all `n` values, or none for `v`
/// when `empty_is_zero`), or by name on top of `latest`.
fn assemble(
    what: &str,
    names: &[String],
    values: &[f64],
    latest: &[f64],
    known: &[String],
    empty_is_zero: bool,
) -> Result<Vec<f64>, String> {
    let n = known.len();
    if names.is_empty() {
        if values.is_empty() && empty_is_zero {
            return Ok(vec![0.0; n]);
        }
        if values.len() != n {
            return Err(format!(
                "{what}: expected {n} values ({}), got {}",
                known.join(", "),
                values.len()
            ));
        }
        check_values(what, values, known)?;
        return Ok(values.to_vec());
    }
    same_len(&format!("{what}_names"), names, what, values.len())?;
    let mut out = latest.to_vec();
    for (name, x) in names.iter().zip(values) {
        let i = known.iter().position(|k| k == name).ok_or_else(|| {
            format!(
                "{what}_names: unknown coordinate '{name}' (known: {})",
                known.join(", ")
            )
        })?;
        if !x.is_finite() {
            return Err(format!("{what}: value of '{name}' is not finite ({x})"));
        }
        out[i] = *x;
    }
    Ok(out)
}

/// Every value finite, naming the coordinate that is not.
fn check_values(what: &str, values: &[f64], names: &[String]) -> Result<(), String> {
    if values.len() != names.len() {
        return Err(format!(
            "{what}: expected {} values ({}), got {}",
            names.len(),
            names.join(", "),
            values.len()
        ));
    }
    match values.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(format!(
            "{what}: value of '{}' (entry {i}) is not finite ({})",
            names[i], values[i]
        )),
        None => Ok(()),
    }
}

fn same_len(a: &str, names: &[String], b: &str, n: usize) -> Result<(), String> {
    if names.len() == n {
        Ok(())
    } else {
        Err(format!(
            "{a} has {} entries but {b} has {n}: they must be the same length",
            names.len()
        ))
    }
}
