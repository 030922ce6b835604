//! The fixture of the suite's end-to-end tests on the bundled mobile manipulator
//! (`suite_services.rs`, `suite_topics.rs`): the robot state fed to the suite, the core
//! library's view of it (computed in the test, independently of the suite's process), the
//! comparison of a `ConstraintForces` message with the core's forces, and the start and stop of
//! a suite beside the test's node.
// Each test binary uses its part.
#![allow(dead_code)]

use super::common::*;
use constraint_dynamics::actuators::{Actuators, Command};
use constraint_dynamics::algorithm::{Data, forward_kinematics_pos, frame_placement};
use constraint_dynamics::applied::constraint_forces_at;
use constraint_dynamics::constraints::ConstraintForce as CoreForce;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::predict::{Predictor, drift};
use constraint_dynamics::{Scene, System};
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::ConstraintForces;
use constraint_dynamics_nodes::msg::geometry_msgs::{Point, Pose, Quaternion};
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;

/// Numbers of the suite against the core's: the same computation in two processes.
pub const TOL: f64 = 1e-9;
/// The command the base already follows (v [m/s], ω [rad/s]): small first-tick torques, no
/// slip at μ = 0.8.
pub const CMD: (f64, f64) = (0.3, 0.4);

/// The scene, the core library beside it, the test's state, and its feed (joint states,
/// odometry, `CMD` on `/cmd_vel`), publishing from the test's node before the suite starts so
/// that its first messages are not missed.
pub struct Fixture {
    pub scene: Scene,
    pub core: Core,
    pub state: TestState,
    pub feed: FeedPublisher,
}

impl Fixture {
    pub fn new(t: &mut TestNode) -> Fixture {
        let scene = Scene::load(repo_root().join("params/suite_mobile_manipulator.yaml")).unwrap();
        let core = Core::new(&scene);
        let state = test_state(&scene);
        let feed = FeedPublisher::start(t);
        feed.set(feed_for(&scene, &state, Some(CMD)));
        Fixture {
            scene,
            core,
            state,
            feed,
        }
    }
}

/// The suite with `params/default.yaml`, as a child process.
pub fn spawn_suite(tag: &str) -> SuiteProcess {
    SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &["--ros-args", "--params-file", "params/default.yaml"],
        tag,
    )
}

/// The suite still runs, stops cleanly on SIGINT, and never panicked.
pub fn stop_suite(mut suite: SuiteProcess) {
    assert!(suite.alive(), "the suite exited");
    assert!(
        suite.stop(),
        "the suite did not exit cleanly on SIGINT:\n{}",
        suite.log()
    );
    let log = suite.log();
    assert!(!log.contains("panicked"), "{log}");
}

/// The robot's state for the test (mobile manipulator, consistent with rolling).
pub struct TestState {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub effort: Vec<f64>,
}

pub fn test_state(scene: &Scene) -> TestState {
    let m = &scene.model;
    let mut q = vec![0.0; m.nq];
    let mut v = vec![0.0; m.nv];
    let mut effort = vec![0.0; m.nv];
    let (vx, wz) = (0.3, 0.4);
    q[..3].copy_from_slice(&[1.0, -0.5, 0.3]);
    v[..3].copy_from_slice(&[vx, 0.0, wz]);
    for (name, qi, vi, ei) in [
        ("left_wheel_joint", 0.7, (vx - 0.17 * wz) / 0.05, 0.05),
        ("right_wheel_joint", -1.2, (vx + 0.17 * wz) / 0.05, 0.08),
        ("arm_shoulder_yaw", 0.2, 0.1, 1.0),
        ("arm_shoulder_pitch", 0.6, -0.2, 2.0),
        ("arm_elbow", 0.9, 0.05, 0.5),
        ("arm_wrist", 0.4, 0.0, 0.1),
    ] {
        q[m.q_index(name).unwrap()] = qi;
        let iv = m.v_index(name).unwrap();
        v[iv] = vi;
        effort[iv] = ei;
    }
    TestState { q, v, effort }
}

pub fn feed_for(scene: &Scene, s: &TestState, cmd: Option<(f64, f64)>) -> RobotFeed {
    let m = &scene.model;
    let mut js = JointState::default();
    for name in [
        "left_wheel_joint",
        "right_wheel_joint",
        "arm_shoulder_yaw",
        "arm_shoulder_pitch",
        "arm_elbow",
        "arm_wrist",
    ] {
        js.name.push(name.into());
        js.position.push(s.q[m.q_index(name).unwrap()]);
        js.velocity.push(s.v[m.v_index(name).unwrap()]);
        js.effort.push(s.effort[m.v_index(name).unwrap()]);
    }
    // A joint the model does not have is ignored.
    js.name.push("gripper_finger_joint".into());
    js.position.push(0.01);
    js.velocity.push(0.0);
    js.effort.push(0.0);
    let mut od = Odometry::default();
    od.header.frame_id = "odom".into();
    od.child_frame_id = "base_footprint".into();
    od.pose.pose = Pose {
        position: Point {
            x: s.q[0],
            y: s.q[1],
            z: 0.0,
        },
        orientation: Quaternion {
            x: 0.0,
            y: 0.0,
            z: (s.q[2] / 2.0).sin(),
            w: (s.q[2] / 2.0).cos(),
        },
    };
    od.twist.twist = twist(s.v[0], s.v[2]);
    od.twist.twist.linear.y = s.v[1];
    RobotFeed {
        joint_state: Some(js),
        odom: Some(od),
        cmd_vel: cmd.map(|(v, w)| twist(v, w)),
    }
}

/// The core library's view: system (multipliers), predictor, force elements, controllers.
pub struct Core {
    pub scene: Scene,
    pub sys: System,
    pub predictor: Predictor,
    /// The scene's force elements (as the predictor's).
    pub forces: ForceElements,
    /// The scene's controllers at rest (as the predictor's).
    pub actuators: Actuators,
}

impl Core {
    pub fn new(scene: &Scene) -> Core {
        let mut sys = System::from_scene(scene).unwrap();
        sys = sys.with_formulation(Formulation::Multipliers);
        Core {
            scene: scene.clone(),
            sys,
            predictor: Predictor::from_scene(scene).unwrap(),
            forces: ForceElements::new(&scene.model, &scene.file.forces).unwrap(),
            actuators: Actuators::new(&scene.model, &scene.file.actuators).unwrap(),
        }
    }

    /// The state as the node uses it: projected onto the constraints.
    pub fn projected(&mut self, q: &[f64], v: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (mut q, mut v) = (q.to_vec(), v.to_vec());
        drift::project(&mut self.sys, &mut q, &mut v, true).unwrap();
        (q, v)
    }

    /// q̈, forces, Jᵀλ at (q, v) under actuator torques plus the scene's force elements.
    pub fn forces(
        &mut self,
        q: &[f64],
        v: &[f64],
        tau_act: &[f64],
    ) -> (Vec<f64>, Vec<CoreForce>, Vec<f64>) {
        let at =
            constraint_forces_at(&mut self.sys, &mut self.forces, (0.0, q, v), tau_act).unwrap();
        (at.qdd, at.forces, at.generalized_force)
    }

    /// The command the nodes build: base twist, arm held at q.
    pub fn command(&self, base: [f64; 2], q: &[f64]) -> Command {
        let mut c = Command {
            base_twist: Some(base),
            ..Default::default()
        };
        for p in &self.scene.file.actuators.position {
            c.joint_position.insert(
                p.joint.clone(),
                q[self.scene.model.q_index(&p.joint).unwrap()],
            );
        }
        c
    }

    pub fn frame_origin(&mut self, q: &[f64], frame: &str) -> Option<[f64; 3]> {
        let id = self.sys.model().frame_id(frame).ok()?;
        let mut data = Data::new(self.sys.model());
        forward_kinematics_pos(self.sys.model(), &mut data, q);
        let t = frame_placement(self.sys.model(), &data, id).translation;
        Some([t.x, t.y, t.z])
    }
}

pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The message's forces equal the core's (wrench moved to the frame origin, "world" = odom).
pub fn check_forces(
    core: &mut Core,
    q: &[f64],
    msg: &ConstraintForces,
    expected: &[CoreForce],
    gf: &[f64],
    tol: f64,
) -> Result<(), String> {
    if msg.constraints.len() != expected.len() {
        return Err(format!(
            "{} constraints vs {}",
            msg.constraints.len(),
            expected.len()
        ));
    }
    close("generalized_force", &msg.generalized_force, gf, tol)?;
    if msg.v_names != core.sys.model().v_names {
        return Err("v_names".into());
    }
    if msg.header.frame_id != "odom" {
        return Err(format!("header.frame_id {}", msg.header.frame_id));
    }
    let m_g = core.sys.model().total_mass() * 9.81 / 2.0;
    for (c, f) in msg.constraints.iter().zip(expected) {
        if c.name != f.name
            || c.kind != f.kind.name()
            || c.frame_id != f.frame
            || c.row_names != f.rows
        {
            return Err(format!("names of {} ({:?} vs {:?})", f.name, c, f));
        }
        if c.axes_frame_id != "odom" {
            return Err(format!("axes_frame_id {}", c.axes_frame_id));
        }
        close(
            &format!("{} lambda", f.name),
            &c.multipliers,
            &f.lambda,
            tol,
        )?;
        let w = &c.wrench;
        close(
            &format!("{} force", f.name),
            &[w.force.x, w.force.y, w.force.z],
            &f.force,
            tol,
        )?;
        let o = core.frame_origin(q, &f.frame).ok_or("frame")?;
        let r = [
            f.point_world[0] - o[0],
            f.point_world[1] - o[1],
            f.point_world[2] - o[2],
        ];
        let t = cross(r, f.force);
        close(
            &format!("{} torque at {}", f.name, f.frame),
            &[w.torque.x, w.torque.y, w.torque.z],
            &[f.torque[0] + t[0], f.torque[1] + t[1], f.torque[2] + t[2]],
            tol,
        )?;
        close(
            &format!("{} position residual", f.name),
            &c.position_residual,
            &f.position_residual,
            tol,
        )?;
        close(
            &format!("{} velocity residual", f.name),
            &c.velocity_residual,
            &f.velocity_residual,
            tol,
        )?;
        close(
            &format!("{} tangential", f.name),
            &[c.tangential_force],
            &[f.tangential_force.unwrap()],
            tol,
        )?;
        // Planar base: no normal row, the node uses m g / 2 per wheel.
        close(
            &format!("{} normal", f.name),
            &[c.normal_force],
            &[m_g],
            tol,
        )?;
        let slipping = f.tangential_force.unwrap() > 0.8 * m_g;
        if c.slipping != slipping {
            return Err(format!("{} slipping flag {}", f.name, c.slipping));
        }
    }
    Ok(())
}

pub fn pose_of(p: &Pose) -> [f64; 3] {
    [p.position.x, p.position.y, yaw(&p.orientation)]
}
