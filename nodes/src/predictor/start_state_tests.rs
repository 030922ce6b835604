//! A start state assembled from odometry and joint states of slightly different instants is off
//! the constraints; its forces must be those of the robot, not of the mismatch. The bundled
//! mobile manipulator speeding into a turn under its controllers (the core's prediction, on the
//! constraints, stands for the robot) is fed to the node with its odometry 20 ms older than its
//! joint states: the rolling rows are then off by the 20 ms of acceleration.

use super::*;
use crate::convert::quaternion_from_yaw;
use crate::msg::geometry_msgs::Vector3;
use crate::msg::sensor_msgs::JointState;
use crate::params::CommonParams;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{PredictionRequest, Sample};

fn node(project: bool) -> PredictorNode {
    let mut common = CommonParams::default();
    common.model.scene_file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/suite_mobile_manipulator.yaml"
    )
    .into();
    common.state.project_to_constraints = project;
    let mut params = NodeParams::<PredictorParams> {
        common,
        node: PredictorParams::default(),
    };
    params.node.horizon = 1.0;
    let robot = Robot::load(&params.common).unwrap();
    PredictorNode::new(robot, params, NodeLog::new("test")).unwrap()
}

/// (v, ω) of the turn.
const TURN: [f64; 2] = [0.5, 1.0];

/// The robot 0.18 s and 0.20 s into a turn from the scene's initial state (0.2 m/s straight),
/// still speeding up (the core's prediction at 2 ms steps).
fn robot_in_a_turn() -> (Sample, Sample) {
    let scene = Scene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/suite_mobile_manipulator.yaml"
    ))
    .unwrap();
    let mut p = Predictor::from_scene(&scene)
        .unwrap()
        .with_settings(|s| {
            s.dt = 0.002;
            s.error_estimate = false;
        })
        .unwrap();
    let (q, v) = (scene.q0.clone(), scene.v0.clone());
    // The arm held where it starts, as the node holds it (`command.hold_joints`).
    let arm = [
        "arm_shoulder_yaw",
        "arm_shoulder_pitch",
        "arm_elbow",
        "arm_wrist",
    ];
    let held = arm.map(|j| (j.to_string(), q[scene.model.q_index(j).unwrap()]));
    let commands = [(
        0.0,
        Command {
            base_twist: Some(TURN),
            joint_position: held.into_iter().collect(),
            ..Default::default()
        },
    )];
    let traj = p
        .predict(&PredictionRequest {
            commands: &commands,
            horizon: Some(0.2),
            ..PredictionRequest::new(&q, &v)
        })
        .unwrap();
    let n = traj.samples.len();
    (traj.samples[n - 2].clone(), traj.samples[n - 1].clone())
}

/// The node's state: the base from `odom`, the joints from `joints`; the turn commanded.
fn feed(n: &mut PredictorNode, odom: &Sample, joints: &Sample, now: Time) {
    let mut od = Odometry::default();
    od.pose.pose.position.x = odom.q[0];
    od.pose.pose.position.y = odom.q[1];
    od.pose.pose.orientation = quaternion_from_yaw(odom.q[2]);
    od.twist.twist.linear.x = odom.v[0];
    od.twist.twist.linear.y = odom.v[1];
    od.twist.twist.angular.z = odom.v[2];
    let model = n.robot.model().clone();
    let js = JointState {
        name: model.q_names[3..].to_vec(),
        position: joints.q[3..].to_vec(),
        velocity: joints.v[3..].to_vec(),
        ..Default::default()
    };
    let st = n.robot.state_mut();
    st.apply_odometry(&model, &od).unwrap();
    st.apply_joint_state(&js).unwrap();
    st.odom_at = Some(now);
    st.joint_states_at = Some(now);
    let cmd = Twist {
        linear: Vector3 {
            x: TURN[0],
            ..Default::default()
        },
        angular: Vector3 {
            z: TURN[1],
            ..Default::default()
        },
    };
    n.handle(PredictorInput::Command(cmd), now, &mut |_| {});
}

fn tick(n: &mut PredictorNode, now: Time) -> PeriodicOutput {
    let mut out = None;
    n.tick(now, &mut |o| out = Some(o)).unwrap();
    *out.expect("a tick publishes")
}

/// The tangential force on each contact [N].
fn tangential(o: &PeriodicOutput) -> Vec<f64> {
    o.forces
        .constraints
        .iter()
        .map(|c| c.tangential_force)
        .collect()
}

/// Odometry 20 ms older than the joint states during a 1 rad/s turn: projected onto the
/// constraints by the node (`state.project_to_constraints`, the default) or by the prediction
/// for its forces and envelope (false), the start forces stay within 2 N of those of the
/// consistent state — against 45 N of friction available — nothing is WARNed (no slip, no
/// infeasible envelope), and `/diagnostics` says how far off the start was. The 2 N are the
/// controllers' answer to the state, not the constraints': the mass-weighted projection moves
/// the light wheels' rates to the older base twist, by about ‖J v‖/r = 4.4e-3/0.05 = 0.09 rad/s,
/// which the PI wheel controllers (kp = 1 N·m·s/rad) answer with 0.09 N·m, 1.8 N at r = 0.05 m.
#[test]
fn a_start_with_odometry_older_than_the_joint_states_has_no_phantom_forces() {
    let (older, now_state) = robot_in_a_turn();
    let t0 = Time::from_nanos(1_000_000_000);
    for project in [true, false] {
        let mut exact = node(project);
        feed(&mut exact, &now_state, &now_state, t0);
        let want = tangential(&tick(&mut exact, t0));
        let mut lagged = node(project);
        feed(&mut lagged, &older, &now_state, t0);
        let out = tick(&mut lagged, t0);
        let got = tangential(&out);
        let worst = got
            .iter()
            .zip(&want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let off = lagged
            .diagnostics()
            .into_iter()
            .find(|v| v.key == "start state off the constraints")
            .expect("the start's residual in /diagnostics")
            .value;
        println!(
            "project {project}: tangential {got:?} vs {want:?} N (worst {worst:.3e} N); {off}; \
             warnings {:?}",
            lagged.warnings()
        );
        assert!(exact.warnings().is_empty(), "{:?}", exact.warnings());
        assert!(lagged.warnings().is_empty(), "{:?}", lagged.warnings());
        assert!(worst < 2.0, "{got:?} vs {want:?}");
    }
}
