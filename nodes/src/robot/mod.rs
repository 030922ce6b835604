//! The robot a node serves: its scene (model, constraints, actuators) with a multiplier-form
//! [`System`], and the latest state assembled from `/joint_states` and `/odom`. Every node kind
//! has one; what a kind builds on top (predictor, projector, force elements) is its own.
//!
//! No ROS handles here: inputs and results are the plain message structs of [`crate::msg`].

pub mod inputs;
pub mod request;
pub mod state;

use constraint_dynamics::actuators::Command;
use constraint_dynamics::constraints::{ContactLimits, ContactState};
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::model::Payload;
use constraint_dynamics::predict::{ContactJudge, DriftProjector, OffConstraints};
use constraint_dynamics::{Model, Scene, System};

use crate::convert::{ForcesAt, ForcesContext, base_twist_of, constraint_forces_msg};
use crate::error::NodeError;
use crate::msg::builtin_interfaces::Time;
use crate::msg::constraint_dynamics_msgs::ConstraintForces;
use crate::msg::geometry_msgs::Twist;
use crate::msg::nav_msgs::Odometry;
use crate::params::{CommonParams, Fallback};
use state::StateEstimate;

/// A scene-bound robot and its latest state. See the module documentation.
#[derive(Clone)]
pub struct Robot {
    scene: Scene,
    /// Multiplier form, so λ is always there (forces, projection, state projection).
    sys: System,
    /// With sideways tyres (`lateral: tyre`), the same rigid sideways for the instantaneous
    /// answers ([`Robot::kinematic_system`]).
    kinematic: Option<System>,
    /// The system's contacts: how every force this robot reports is judged.
    contacts: ContactJudge,
    state: StateEstimate,
    /// Joints with position controllers in the scene, and their q index.
    held_joints: Vec<(String, usize)>,
    base_frame: String,
    /// How far the last projected latest state lay off the constraints (None before one).
    off_constraints: Option<OffConstraints>,
}

impl Robot {
    /// Loads the scene file named in the parameters (already resolved to a path), carrying the
    /// `payload.*` parameters' payload when they name one (else the scene's).
    pub fn load(common: &CommonParams) -> Result<Self, NodeError> {
        let path = &common.model.scene_file;
        let scene_err = |source| NodeError::Scene {
            path: path.clone(),
            source,
        };
        let mut scene = Scene::load(path).map_err(scene_err)?;
        if let Some(p) = common.payload.payload()? {
            scene = scene.with_payload(&p).map_err(scene_err)?;
        }
        Self::from_scene(scene, common)
    }

    /// The same robot carrying `payload` instead (mass 0: none), the state carried over. The
    /// current robot is untouched: on an error (naming the payload's field) it stays in use.
    pub fn with_payload(
        &self,
        payload: &Payload,
        common: &CommonParams,
    ) -> Result<Robot, NodeError> {
        let scene = self
            .scene
            .with_payload(payload)
            .map_err(NodeError::core("payload"))?;
        let mut next = Robot::from_scene(scene, common)?;
        next.state.carry_over(&self.state);
        Ok(next)
    }

    /// The payload the model carries.
    pub fn payload(&self) -> &Payload {
        &self.scene.payload
    }

    /// Builds the system and the state estimate (at the scene's initial state) of a scene.
    pub fn from_scene(scene: Scene, common: &CommonParams) -> Result<Self, NodeError> {
        let sys = System::from_scene(&scene)
            .map_err(NodeError::core("constraints"))?
            .with_formulation(Formulation::Multipliers);
        let kinematic = match scene.has_sideways_tyres() {
            true => Some(
                System::from_scene(&scene.rigid_sideways())
                    .map_err(NodeError::core("constraints"))?
                    .with_formulation(Formulation::Multipliers),
            ),
            false => None,
        };
        let contacts = ContactJudge::new(&scene.model, sys.constraints());
        let state = StateEstimate::new(&scene.model, &scene.q0, &scene.v0);
        let held_joints = scene
            .file
            .actuators
            .position
            .iter()
            .filter_map(|c| state.joint(&c.joint).map(|(iq, _)| (c.joint.clone(), iq)))
            .collect();
        let base_frame = match common.frames.base_frame.as_str() {
            "" => scene
                .model
                .bodies
                .get(1)
                .map(|b| b.name.clone())
                .unwrap_or_else(|| "base_link".into()),
            f => f.to_string(),
        };
        Ok(Robot {
            scene,
            sys,
            kinematic,
            contacts,
            state,
            held_joints,
            base_frame,
            off_constraints: None,
        })
    }

    /// The same scene settings and payload with the URDF of a `/robot_description` message;
    /// the state is carried over by name.
    pub fn with_urdf(&self, urdf: &str, common: &CommonParams) -> Result<Robot, NodeError> {
        if urdf.trim().is_empty() {
            return Err(NodeError::EmptyUrdf);
        }
        let scene = Scene::from_parts(
            &self.scene.path,
            self.scene.file.clone(),
            urdf,
            "robot_description",
        )
        .and_then(|s| s.with_payload(&self.scene.payload))
        .map_err(NodeError::core("robot_description"))?;
        let mut next = Robot::from_scene(scene, common)?;
        next.state.carry_over(&self.state);
        Ok(next)
    }

    /// A fresh robot from the same scene, keeping the state (after a caught panic).
    pub fn rebuilt(&self, common: &CommonParams) -> Result<Robot, NodeError> {
        let mut next = Robot::from_scene(self.scene.clone(), common)?;
        next.state.carry_over(&self.state);
        Ok(next)
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.scene.model
    }

    /// The constraints' names, in the system's order.
    pub fn constraint_names(&self) -> &[String] {
        &self.sys.constraints().names
    }

    /// The multiplier-form system.
    pub fn system(&mut self) -> &mut System {
        &mut self.sys
    }

    /// The system the velocity projection takes: the robot's own, rigid sideways where a tyre
    /// holds a wheel sideways (its creep is a slip its force builds over time, not a velocity a
    /// command can ask for).
    pub fn kinematic_system(&mut self) -> &mut System {
        match self.kinematic.as_mut() {
            Some(k) => k,
            None => &mut self.sys,
        }
    }

    /// The latest state.
    pub fn state(&self) -> &StateEstimate {
        &self.state
    }

    /// Applies an `/odom` message to the latest state with this robot's model (borrowed, not
    /// copied: a message allocates nothing).
    pub fn apply_odometry(&mut self, od: &Odometry) -> Result<(), NodeError> {
        self.state.apply_odometry(&self.scene.model, od)
    }

    /// The latest state, to apply messages to.
    pub fn state_mut(&mut self) -> &mut StateEstimate {
        &mut self.state
    }

    /// The child frame of the predicted odometry.
    pub fn base_frame(&self) -> &str {
        &self.base_frame
    }

    /// The latest state (normalised), projected onto the constraints when `project` (as the
    /// predictor's drift control does, mass-weighted; how far off it was is
    /// [`Robot::off_constraints`]). Odometry and joint states of slightly different instants
    /// are never exactly on the constraints.
    pub fn latest_state(&mut self, project: bool) -> Result<(Vec<f64>, Vec<f64>), NodeError> {
        let (mut q, mut v) = (self.state.q.clone(), self.state.v.clone());
        self.scene.model.normalize(&mut q);
        if project {
            let off = DriftProjector::new(&self.sys)
                .project_measured(&mut self.sys, &mut q, &mut v)
                .map_err(NodeError::core(
                    "latest state: projection onto the constraints",
                ))?;
            self.off_constraints = Some(off);
        }
        Ok((q, v))
    }

    /// How far the last projected latest state lay off the constraints.
    pub fn off_constraints(&self) -> Option<OffConstraints> {
        self.off_constraints
    }

    /// True if the scene has a differential drive that follows base twists.
    pub fn has_diff_drive(&self) -> bool {
        self.scene.file.actuators.diff_drive.is_some()
    }

    /// The core command for a base (v, ω), holding the position-controlled joints at `q0` when
    /// `hold_joints`.
    pub fn command(&self, base: Option<[f64; 2]>, q0: &[f64], hold_joints: bool) -> Command {
        let mut cmd = Command {
            base_twist: if self.has_diff_drive() { base } else { None },
            ..Default::default()
        };
        if hold_joints {
            for (name, iq) in &self.held_joints {
                cmd.joint_position.insert(name.clone(), q0[*iq]);
            }
        }
        cmd
    }

    /// The base (v, ω) used without a fresh command; `None` = coast.
    pub fn fallback_twist(&self, fallback: Fallback, v0: &[f64]) -> Option<[f64; 2]> {
        match fallback {
            Fallback::Hold => {
                let t = self.scene.model.base_twist(v0);
                Some([t.linear[0], t.angular[2]])
            }
            Fallback::Coast => None,
            Fallback::Stop => Some([0.0, 0.0]),
        }
    }

    /// (v, ω) of a twist command, refusing what a differential drive cannot do.
    pub fn twist_command(&self, t: &Twist, what: &str) -> Result<[f64; 2], NodeError> {
        let vw = base_twist_of(t)
            .unicycle()
            .map_err(|e| NodeError::request(what, e.to_string()))?;
        if !self.has_diff_drive() {
            return Err(NodeError::request(
                what,
                format!(
                    "the scene {} has no actuators.diff_drive, so it cannot follow base twists",
                    self.scene.path.display()
                ),
            ));
        }
        Ok(vw)
    }

    /// What the judgement of this robot's contacts assumes under the parameters: μ =
    /// `slip.friction_coefficient` where a contact declares none, and a wheel without a normal
    /// row pressed by `slip.planar_normal_force` (0: its share of the weight).
    pub fn contact_limits(&self, common: &CommonParams) -> ContactLimits {
        ContactLimits::assumed(
            &self.scene.model,
            self.sys.constraints(),
            common.slip.friction_coefficient,
            common.slip.planar_normal_force,
        )
    }

    /// The system's contacts, judged as a prediction judges them.
    pub fn contact_judge(&self) -> &ContactJudge {
        &self.contacts
    }

    /// The contacts judged at `lambda` under `limits` as a prediction judges them, a sideways
    /// tyre's friction from `elements` at the state the system last solved
    /// (`constraint_forces_at`'s).
    pub fn judge_contacts(
        &self,
        lambda: &[f64],
        limits: &ContactLimits,
        elements: &ForceElements,
    ) -> Option<Vec<ContactState>> {
        let (model, data) = (self.sys.model(), self.sys.data());
        self.contacts.judge(lambda, limits, model, data, elements)
    }

    /// A `ConstraintForces` message in the odom frame.
    pub fn forces_msg(
        &self,
        common: &CommonParams,
        at: &ForcesAt,
        stamp: Time,
    ) -> ConstraintForces {
        let ctx = ForcesContext {
            stamp,
            world_frame: &common.frames.odom_frame,
            v_names: &self.scene.model.v_names,
            contacts: &self.contacts,
        };
        constraint_forces_msg(at, &ctx)
    }

    /// The start state of a request: the latest (projected per the parameters), or the
    /// request's own q (positional, all nq) and v (positional, all nv or none = zero).
    pub fn request_state(
        &mut self,
        common: &CommonParams,
        use_latest: bool,
        (q_names, q): (&[String], &[f64]),
        (v_names, v): (&[String], &[f64]),
    ) -> Result<(Vec<f64>, Vec<f64>), NodeError> {
        if use_latest {
            return self.latest_state(common.state.project_to_constraints);
        }
        let model = &self.scene.model;
        let mut q = request::assemble("q", q_names, q, &self.state.q, &model.q_names, false)?;
        let v = request::assemble("v", v_names, v, &self.state.v, &model.v_names, true)?;
        model.normalize(&mut q);
        Ok((q, v))
    }
}
