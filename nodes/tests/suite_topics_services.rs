//! The suite end to end on the bundled mobile manipulator (`params/default.yaml`): the
//! `constraint_dynamics_suite` binary runs as a child process in this test's loopback-only
//! network namespace; the test feeds it a robot state (`/joint_states`, `/odom`) and a command
//! (`/cmd_vel`), calls every service and reads every topic with ros2-client, and compares each
//! number with the core library's for the same state (computed here).
//!
//! Also: the parameter services (list/get, a refused and an accepted set), the slip warning
//! (flag in the message + `/rosout`) and a model change through `/robot_description`.

mod common;

use std::collections::BTreeMap;
use std::time::Duration;

use common::*;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::algorithm::{forward_kinematics_pos, frame_placement};
use constraint_dynamics::applied::constraint_forces_at;
use constraint_dynamics::constraints::ConstraintForce as CoreForce;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::predict::{PredictOptions, Predictor, drift};
use constraint_dynamics::projection::{
    PerCoordinate, ProjectionRequest, Status, VelocityProjector, project_system,
};
use constraint_dynamics::{Scene, System};
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::ConstraintForces;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesRequest, Predict, PredictRequest, ProjectVelocity,
    ProjectVelocityRequest, Rollouts, RolloutsRequest,
};
use constraint_dynamics_nodes::msg::geometry_msgs::{Point, Pose, Quaternion};
use constraint_dynamics_nodes::msg::nav_msgs::{Odometry, Path};
use constraint_dynamics_nodes::msg::rcl_interfaces::{
    GetParameters, ListParameters, SetParameters,
};
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::msg::std_msgs::StringMsg;
use ros2_client::ParameterValue;
use ros2_client::parameters::raw;
use ros2_client::rcl_interfaces::{
    GetParametersRequest, ListParametersRequest, SetParametersRequest,
};

const TEST: &str = "suite_matches_the_core_library";
const TOL: f64 = 1e-9;

/// The robot's state for the test (mobile manipulator, consistent with rolling).
struct TestState {
    q: Vec<f64>,
    v: Vec<f64>,
    effort: Vec<f64>,
}

fn test_state(scene: &Scene) -> TestState {
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

fn feed_for(scene: &Scene, s: &TestState, cmd: Option<(f64, f64)>) -> RobotFeed {
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

/// The core library's view: system (multipliers), predictor, force elements.
struct Core {
    scene: Scene,
    sys: System,
    predictor: Predictor,
}

impl Core {
    fn new(scene: &Scene) -> Core {
        let mut sys = System::from_scene(scene).unwrap();
        sys.formulation = Formulation::Multipliers;
        Core {
            scene: scene.clone(),
            sys,
            predictor: Predictor::from_scene(scene).unwrap(),
        }
    }

    /// The state as the node uses it: projected onto the constraints.
    fn projected(&mut self, q: &[f64], v: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (mut q, mut v) = (q.to_vec(), v.to_vec());
        drift::project(&mut self.sys, &mut q, &mut v, true).unwrap();
        (q, v)
    }

    /// q̈, forces, Jᵀλ at (q, v) under actuator torques plus the scene's force elements.
    fn forces(
        &mut self,
        q: &[f64],
        v: &[f64],
        tau_act: &[f64],
    ) -> (Vec<f64>, Vec<CoreForce>, Vec<f64>) {
        let at = constraint_forces_at(
            &mut self.sys,
            &mut self.predictor.forces,
            (0.0, q, v),
            tau_act,
        )
        .unwrap();
        (at.qdd, at.forces, at.generalized_force)
    }

    /// The command the nodes build: base twist, arm held at q.
    fn command(&self, base: [f64; 2], q: &[f64]) -> Command {
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

    fn frame_origin(&mut self, q: &[f64], frame: &str) -> Option<[f64; 3]> {
        let id = self.sys.model.frame_id(frame).ok()?;
        forward_kinematics_pos(&self.sys.model, &mut self.sys.data, q);
        let t = frame_placement(&self.sys.model, &self.sys.data, id).translation;
        Some([t.x, t.y, t.z])
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The message's forces equal the core's (wrench moved to the frame origin, "world" = odom).
fn check_forces(
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
    if msg.v_names != core.sys.model.v_names {
        return Err("v_names".into());
    }
    if msg.header.frame_id != "odom" {
        return Err(format!("header.frame_id {}", msg.header.frame_id));
    }
    let m_g = core.sys.model.total_mass() * 9.81 / 2.0;
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

fn yaw(q: &Quaternion) -> f64 {
    (2.0 * (q.w * q.z + q.x * q.y)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z))
}

fn pose_of(p: &Pose) -> [f64; 3] {
    [p.position.x, p.position.y, yaw(&p.orientation)]
}

fn raw_value(v: ParameterValue) -> raw::ParameterValue {
    v.into()
}

#[test]
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn suite_matches_the_core_library() {
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let scene = Scene::load(repo_root().join("params/suite_mobile_manipulator.yaml")).unwrap();
    let mut core = Core::new(&scene);
    let state = test_state(&scene);

    // The test's node first (so the first messages are not missed), then the suite.
    let mut t = TestNode::new("cd_test");
    let feed = FeedPublisher::start(&mut t);
    // The command the base already follows: small first-tick torques, no slip at μ = 0.8.
    let cmd = (0.3, 0.4);
    feed.set(feed_for(&scene, &state, Some(cmd)));
    let odom_sub = t.subscribe::<Odometry>("/cd_predictor/predicted_odom");
    let path_sub = t.subscribe::<Path>("/cd_predictor/predicted_path");
    let forces_sub = t.subscribe::<ConstraintForces>("/cd_predictor/constraint_forces");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &["--ros-args", "--params-file", "params/default.yaml"],
        "topics",
    );

    // ---- ~/get_constraint_forces at the latest state (waits until the feed is applied) ----
    let forces = t.client::<GetConstraintForces>("/cd_forces/get_constraint_forces");
    let (ql, vl) = core.projected(&state.q, &state.v);
    let (qdd, f, gf) = core.forces(&ql, &vl, &state.effort);
    let latest = GetConstraintForcesRequest {
        use_latest_state: true,
        ..Default::default()
    };
    let deadline = std::time::Instant::now() + WAIT;
    loop {
        let r = call(&forces, latest.clone());
        assert!(r.success, "{}", r.message);
        let check = close("qdd", &r.qdd, &qdd, TOL)
            .and_then(|_| check_forces(&mut core, &ql, &r.forces, &f, &gf, TOL));
        match check {
            Ok(()) => break,
            Err(e) if std::time::Instant::now() > deadline => {
                panic!("latest-state forces never matched the core: {e}")
            }
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    println!("{TEST}: get_constraint_forces (latest state, measured efforts) = core");

    // ---- ~/get_constraint_forces at a state in the request --------------------------------
    let mut q2 = state.q.clone();
    q2[2] = -1.1;
    let mut v2 = state.v.clone();
    v2[5] = 0.7;
    let tau2: Vec<f64> = (0..scene.model.nv).map(|i| 0.1 * i as f64 - 0.3).collect();
    let r = call(
        &forces,
        GetConstraintForcesRequest {
            use_latest_state: false,
            q: q2.clone(),
            v: v2.clone(),
            tau: tau2.clone(),
            ..Default::default()
        },
    );
    assert!(r.success, "{}", r.message);
    let (qdd, f, gf) = core.forces(&q2, &v2, &tau2);
    assert_close("qdd (request state)", &r.qdd, &qdd, TOL);
    check_forces(&mut core, &q2, &r.forces, &f, &gf, TOL).unwrap();
    // By name: only the elbow changes, the rest is the latest state.
    let r = call(
        &forces,
        GetConstraintForcesRequest {
            q_names: vec!["arm_elbow".into()],
            q: vec![1.4],
            v_names: vec!["arm_elbow".into()],
            v: vec![-0.3],
            ..Default::default()
        },
    );
    assert!(r.success, "{}", r.message);
    let (mut q3, mut v3) = (state.q.clone(), state.v.clone());
    q3[scene.model.q_index("arm_elbow").unwrap()] = 1.4;
    v3[scene.model.v_index("arm_elbow").unwrap()] = -0.3;
    let (qdd, f, gf) = core.forces(&q3, &v3, &vec![0.0; scene.model.nv]);
    assert_close("qdd (named state)", &r.qdd, &qdd, TOL);
    check_forces(&mut core, &q3, &r.forces, &f, &gf, TOL).unwrap();
    println!("{TEST}: get_constraint_forces (state in the request, positional and by name) = core");

    // ---- ~/project_velocity -------------------------------------------------------------------
    let project = t.client::<ProjectVelocity>("/cd_projection/project_velocity");
    let mut req = ProjectVelocityRequest {
        use_latest_state: true,
        use_twist: true,
        joint_names: vec!["arm_elbow".into()],
        joint_velocities: vec![0.3],
        bound_names: vec!["right_wheel_joint".into()],
        lower: vec![f64::NEG_INFINITY],
        upper: vec![6.0],
        ..Default::default()
    };
    req.base_twist = twist(0.4, 0.5);
    req.base_twist.linear.y = 0.1;
    let r = call(&project, req);
    let mut pr = ProjectionRequest {
        base_twist: Some(vec![0.4, 0.1, 0.5]),
        lower: Some(PerCoordinate::Named(BTreeMap::from([(
            "right_wheel_joint".to_string(),
            None,
        )]))),
        upper: Some(PerCoordinate::Named(BTreeMap::from([(
            "right_wheel_joint".to_string(),
            Some(6.0),
        )]))),
        ..Default::default()
    };
    pr.joints.insert("arm_elbow".into(), 0.3);
    let mut projector = VelocityProjector::new(&core.sys.model, &core.sys.constraints);
    let expected = project_system(&mut projector, &mut core.sys, &ql, &vl, &pr).unwrap();
    assert_eq!(expected.status, Status::Optimal);
    assert!(
        r.success && r.status == "optimal",
        "{} {}",
        r.status,
        r.message
    );
    let ev = expected.v.clone().unwrap();
    assert_close("projected v", &r.v, &ev, TOL);
    assert_close(
        "impulses",
        &r.impulses,
        &expected.impulses.clone().unwrap(),
        1e-7,
    );
    assert_close(
        "base twist",
        &[
            r.base_twist.linear.x,
            r.base_twist.linear.y,
            r.base_twist.angular.z,
        ],
        &ev[..3],
        TOL,
    );
    assert_eq!(r.v_names, scene.model.v_names);
    let expected_bounds: Vec<String> = expected
        .active_bounds
        .iter()
        .map(|b| {
            let side = match b.side {
                constraint_dynamics::projection::Side::Lower => ">=",
                constraint_dynamics::projection::Side::Upper => "<=",
            };
            format!("{} {side} {} ({})", b.coordinate, b.value, b.source.label())
        })
        .collect();
    assert_eq!(r.active_bounds, expected_bounds);
    println!(
        "{TEST}: project_velocity = core ({}; active {:?})",
        r.message, r.active_bounds
    );

    // ---- ~/predict ----------------------------------------------------------------------------
    let predict = t.client::<Predict>("/cd_prediction/predict");
    let commands = [(0.4, 0.3), (0.2, -0.5)];
    let r = call(
        &predict,
        PredictRequest {
            use_latest_state: false,
            q: state.q.clone(),
            v: state.v.clone(),
            commands: commands.iter().map(|&(v, w)| twist(v, w)).collect(),
            command_period: 0.5,
            horizon: 1.0,
            with_forces: true,
            ..Default::default()
        },
    );
    assert!(r.success, "{}", r.message);
    let cmds: Vec<(f64, Command)> = commands
        .iter()
        .enumerate()
        .map(|(k, &(v, w))| (0.5 * k as f64, core.command([v, w], &state.q)))
        .collect();
    core.predictor.want_forces = true;
    let traj = core
        .predictor
        .predict(&state.q, &state.v, &cmds, 1.0)
        .unwrap();
    core.predictor.want_forces = false;
    let times: Vec<f64> = traj.samples.iter().map(|s| s.t).collect();
    assert_close("predict times", &r.times, &times, TOL);
    assert_eq!(r.path.poses.len(), traj.samples.len());
    assert_eq!(r.forces.len(), traj.samples.len());
    for (k, (p, s)) in r.path.poses.iter().zip(&traj.samples).enumerate() {
        assert_close(
            &format!("predict pose {k}"),
            &pose_of(&p.pose),
            &s.q[..3],
            TOL,
        );
        let lam: Vec<f64> = r.forces[k]
            .constraints
            .iter()
            .flat_map(|c| c.multipliers.clone())
            .collect();
        assert_close(
            &format!("predict lambda {k}"),
            &lam,
            s.lambda.as_ref().unwrap(),
            1e-8,
        );
    }
    let last = traj.samples.last().unwrap();
    assert_close(
        "position_error_estimate",
        &[r.position_error_estimate],
        &[last.position_error_estimate()],
        1e-6,
    );
    assert_eq!(r.path.header.frame_id, "odom");
    println!(
        "{TEST}: predict ({} samples) = core; {}",
        r.times.len(),
        r.message
    );

    // ---- ~/rollouts: each rollout is the core's single prediction of that sequence -----------
    let rollouts = t.client::<Rollouts>("/cd_prediction/rollouts");
    let sequences = [
        [(0.4, 0.3), (0.2, -0.5)],
        [(0.0, 0.0), (-0.3, 0.8)],
        [(0.5, 0.0), (0.5, 0.0)],
    ];
    let (len, step) = (2, 0.25);
    let r = call(
        &rollouts,
        RolloutsRequest {
            use_latest_state: false,
            q: state.q.clone(),
            v: state.v.clone(),
            commands: sequences
                .iter()
                .flatten()
                .map(|&(v, w)| twist(v, w))
                .collect(),
            sequence_length: len as u32,
            step,
            with_forces: true,
        },
    );
    assert!(r.success, "{}", r.message);
    assert_eq!(r.header.frame_id, "odom");
    assert_eq!((r.poses.len(), r.twists.len(), r.forces.len()), (6, 6, 6));
    for (j, seq) in sequences.iter().enumerate() {
        let cmds: Vec<(f64, Command)> = seq
            .iter()
            .enumerate()
            .map(|(k, &(v, w))| (step * k as f64, core.command([v, w], &state.q)))
            .collect();
        let mut single = Predictor::from_scene(&scene).unwrap();
        single.settings.sample_period = step;
        single.settings.error_estimate = false;
        let forces = PredictOptions { forces: true };
        let traj = single
            .predict_with(&state.q, &state.v, &cmds, len as f64 * step, forces)
            .unwrap();
        assert_eq!(traj.samples.len(), len + 1);
        for (k, s) in traj.samples[1..].iter().enumerate() {
            let i = j * len + k;
            let what = format!("rollout {j} step {k}");
            assert_close(&what, &pose_of(&r.poses[i]), &s.q[..3], TOL);
            let tw = &r.twists[i];
            let expected = scene.model.base_twist(&s.v);
            assert_close(
                &what,
                &[tw.linear.x, tw.linear.y, tw.angular.z],
                &[expected.linear[0], expected.linear[1], expected.angular[2]],
                TOL,
            );
            let lam: Vec<f64> = r.forces[i]
                .constraints
                .iter()
                .flat_map(|c| c.multipliers.clone())
                .collect();
            assert_close(&what, &lam, s.lambda.as_ref().unwrap(), 1e-8);
        }
    }
    println!(
        "{TEST}: rollouts (3 × 2 steps) = core single predictions; {}",
        r.message
    );

    // ---- topics of the predictor (command (0.3, 0.4) on /cmd_vel) -----------------------------
    let expected_cmd = core.command([cmd.0, cmd.1], &ql);
    let traj = core
        .predictor
        .predict(&ql, &vl, &[(0.0, expected_cmd.clone())], 1.0)
        .unwrap();
    let last = traj.samples.last().unwrap().clone();
    let odom = take_until(&odom_sub, WAIT, |m: &Odometry| {
        close("predicted pose", &pose_of(&m.pose.pose), &last.q[..3], TOL)?;
        let t = &m.twist.twist;
        close(
            "predicted twist",
            &[t.linear.x, t.linear.y, t.angular.z],
            &last.v[..3],
            TOL,
        )
    })
    .unwrap_or_else(|e| panic!("predicted_odom never matched the core: {e}"));
    assert_eq!(
        (odom.header.frame_id.as_str(), odom.child_frame_id.as_str()),
        ("odom", "base_footprint")
    );
    let err = last.position_error_estimate();
    let sp = err.hypot(1e-3);
    for i in 0..6 {
        assert!(odom.pose.covariance[i * 7] > 0.0, "covariance[{i}] is zero");
        assert!(odom.twist.covariance[i * 7] > 0.0);
    }
    assert_close(
        "pose covariance x",
        &[odom.pose.covariance[0]],
        &[sp * sp],
        1e-9,
    );
    println!(
        "{TEST}: predicted_odom = core at the horizon: ({:.6}, {:.6}, {:.6}), σ = {sp:.3e} m \
         (error estimate {:.3e})",
        last.q[0],
        last.q[1],
        last.q[2],
        last.error_estimate.unwrap_or(0.0)
    );

    take_until(&path_sub, WAIT, |m: &Path| {
        if m.poses.len() != traj.samples.len() {
            return Err(format!("{} poses vs {}", m.poses.len(), traj.samples.len()));
        }
        for (k, (p, s)) in m.poses.iter().zip(&traj.samples).enumerate() {
            close(&format!("path pose {k}"), &pose_of(&p.pose), &s.q[..3], TOL)?;
        }
        Ok(())
    })
    .unwrap_or_else(|e| panic!("predicted_path never matched the core: {e}"));
    println!(
        "{TEST}: predicted_path = core ({} poses)",
        traj.samples.len()
    );

    // Forces at the start state under the torques of the first control tick.
    let mut act = core.predictor.actuators.clone();
    act.reset();
    let mut tau = vec![0.0; scene.model.nv];
    let dt = act
        .control_period
        .min(core.predictor.settings.sample_period)
        .min(1.0);
    act.update(&expected_cmd, &ql, &vl, dt, &mut tau);
    let (_, f, gf) = core.forces(&ql, &vl, &tau);
    let m = take_until(&forces_sub, WAIT, |m: &ConstraintForces| {
        check_forces(&mut core, &ql, m, &f, &gf, TOL)
    })
    .unwrap_or_else(|e| panic!("constraint_forces never matched the core: {e}"));
    assert!(
        m.constraints.iter().all(|c| !c.slipping),
        "slip at μ = 0.8: {m:?}"
    );
    println!("{TEST}: constraint_forces topic = core (first-tick actuator torques)");

    // ---- parameters ---------------------------------------------------------------------------
    let list = t.client::<ListParameters>("/cd_predictor/list_parameters");
    let names = call(
        &list,
        ListParametersRequest {
            prefixes: vec![],
            depth: 0,
        },
    )
    .result
    .names;
    for n in [
        "rate",
        "horizon",
        "model.scene_file",
        "slip.friction_coefficient",
        "use_sim_time",
    ] {
        assert!(names.iter().any(|x| x == n), "{n} not listed: {names:?}");
    }
    let get = t.client::<GetParameters>("/cd_predictor/get_parameters");
    let values = call(
        &get,
        GetParametersRequest {
            names: vec!["rate".into(), "slip.friction_coefficient".into()],
        },
    )
    .values;
    let values: Vec<ParameterValue> = values.into_iter().map(ParameterValue::from).collect();
    assert_eq!(
        values,
        vec![ParameterValue::Double(10.0), ParameterValue::Double(0.8)]
    );
    let set = t.client::<SetParameters>("/cd_predictor/set_parameters");
    let results = call(
        &set,
        SetParametersRequest {
            parameter: vec![raw::Parameter {
                name: "rate".into(),
                value: raw_value(ParameterValue::Double(50.0)),
            }],
        },
    )
    .results;
    assert!(!results[0].successful);
    assert!(
        results[0].reason.contains("cannot change"),
        "{}",
        results[0].reason
    );
    let results = call(
        &set,
        SetParametersRequest {
            parameter: vec![raw::Parameter {
                name: "slip.friction_coefficient".into(),
                value: raw_value(ParameterValue::Double(-1.0)),
            }],
        },
    )
    .results;
    assert!(!results[0].successful && results[0].reason.contains("friction_coefficient"));
    println!(
        "{TEST}: parameters: {} listed; set rate refused (cannot change while the node runs); \
         μ = -1 refused ({})",
        names.len(),
        results[0].reason
    );

    // ---- slip: μ → 1e-4 makes the turning contacts slip: flag + /rosout warning ----------------
    let results = call(
        &set,
        SetParametersRequest {
            parameter: vec![raw::Parameter {
                name: "slip.friction_coefficient".into(),
                value: raw_value(ParameterValue::Double(1e-4)),
            }],
        },
    )
    .results;
    assert!(results[0].successful, "{}", results[0].reason);
    take_until(&forces_sub, WAIT, |m: &ConstraintForces| {
        if m.constraints.iter().all(|c| c.slipping) {
            Ok(())
        } else {
            Err("not slipping yet".into())
        }
    })
    .unwrap_or_else(|e| panic!("no slip flag after μ = 1e-4: {e}"));
    let log = take_until(t.rosout(), WAIT, |l: &ros2_client::Log| {
        if l.name == "cd_predictor"
            && l.level == ros2_client::Log::WARN
            && l.msg.contains("slip")
            && l.msg.contains("0.0001")
        {
            Ok(())
        } else {
            Err(format!("{}: {}", l.name, l.msg))
        }
    })
    .unwrap_or_else(|e| panic!("no slip warning on /rosout: {e}"));
    println!(
        "{TEST}: slip flagged and logged to /rosout: \"{}\"",
        log.msg
    );

    // ---- /robot_description: a heavier chassis re-plans with the new model ---------------------
    let urdf = std::fs::read_to_string(repo_root().join("urdf/mobile_manipulator.urdf")).unwrap();
    let heavy = urdf.replacen("<mass value=\"8.0\"/>", "<mass value=\"16.0\"/>", 1);
    assert_ne!(heavy, urdf, "chassis mass not found in the URDF");
    let description = description_publisher(&mut t);
    description
        .publish(StringMsg {
            data: heavy.clone(),
        })
        .unwrap();
    let heavy_scene = Scene::from_parts(&scene.path, scene.file.clone(), &heavy, "heavy").unwrap();
    let mut heavy_core = Core::new(&heavy_scene);
    let (qh, vh) = heavy_core.projected(&state.q, &state.v);
    let (qdd_heavy, _, _) = heavy_core.forces(&qh, &vh, &state.effort);
    let deadline = std::time::Instant::now() + WAIT;
    loop {
        let r = call(&forces, latest.clone());
        if close("qdd (heavy)", &r.qdd, &qdd_heavy, TOL).is_ok() {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the forces node did not switch to the new URDF: qdd {:?} vs {:?}",
            r.qdd,
            qdd_heavy
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    println!("{TEST}: /robot_description: model rebuilt, forces = core on the new URDF");

    assert!(suite.alive(), "the suite exited");
    assert!(
        suite.stop(),
        "the suite did not exit cleanly on SIGINT:\n{}",
        suite.log()
    );
    let log = suite.log();
    assert!(!log.contains("panicked"), "{log}");
}
