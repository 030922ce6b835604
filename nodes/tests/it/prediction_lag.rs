//! `cd_prediction` on a drive that follows its commands late (`actuators.diff_drive.command_lag`,
//! no ROS: the node's logic called directly). A request carries no command history, so the lag
//! starts at the start's wheel speeds: from rest, a step to 0.5 m/s under τ = 0.2 s covers
//! 0.5 (1 − τ (1 − e^(−1/τ))) = 0.4007 m in 1 s (a first-order lag's closed form, less the
//! 0.3 mm the wheels' PI loops, their integrals starting at 0, trail their targets by), not the
//! 0.5 m of a drive already on the command; rolling at 0.5 m/s already, the same request covers
//! 0.5 m (less the same 0.3 mm). `~/predict` and `~/rollouts` alike.

use crate::common;

use common::twist;
use constraint_dynamics::Scene;
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    PredictRequest, RolloutsRequest,
};
use constraint_dynamics_nodes::node::worker::NodeLogic;
use constraint_dynamics_nodes::params::{CommonParams, NodeParams};
use constraint_dynamics_nodes::prediction::{PredictionNode, PredictionParams};
use constraint_dynamics_nodes::robot::Robot;
use constraint_dynamics_nodes::ros::logging::NodeLog;

const TAU_S: f64 = 0.2;
const SPEED: f64 = 0.5;
/// The suite drive's wheel radius [m].
const RADIUS: f64 = 0.05;

/// params/suite_diff_drive.yaml with a command lag of [`TAU_S`], written to a temporary file.
fn lagged_scene() -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("cd_prediction_lag_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let params_dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../params");
    let suite = std::fs::read_to_string(format!("{params_dir}/suite_diff_drive.yaml")).unwrap();
    let ki = "    ki: 20.0                     # [N·m/rad]\n";
    assert!(suite.contains(ki), "the suite scene's diff drive moved");
    let lagged = (suite.replace(ki, &format!("{ki}    command_lag: {TAU_S}\n")))
        .replace("urdf: ../urdf/", &format!("urdf: {params_dir}/../urdf/"));
    let file = dir.join("lagged.yaml");
    std::fs::write(&file, lagged).unwrap();
    file
}

/// The distance covered in 1 s under a 0.5 m/s command: by `~/predict` and by `~/rollouts`.
fn travel(node: &mut PredictionNode, q: &[f64], v: &[f64]) -> [f64; 2] {
    let predict = PredictRequest {
        use_latest_state: false,
        q: q.to_vec(),
        v: v.to_vec(),
        commands: vec![twist(SPEED, 0.0)],
        command_period: 1.0,
        horizon: 1.0,
        ..Default::default()
    };
    let r = node.predict(&predict, Time::default());
    assert!(r.success, "{}", r.message);
    let p = &r.path.poses.last().unwrap().pose.position;
    let rollouts = RolloutsRequest {
        use_latest_state: false,
        q: q.to_vec(),
        v: v.to_vec(),
        commands: vec![twist(SPEED, 0.0); 20],
        sequence_length: 20,
        step: 0.05,
        with_forces: false,
    };
    let rr = node.rollouts(&rollouts, Time::default());
    assert!(rr.success, "{}", rr.message);
    let pr = &rr.poses.last().unwrap().position;
    [p.x - q[0], pr.x - q[0]]
}

#[test]
fn a_requested_prediction_starts_the_lag_at_the_wheels_speeds() {
    let _group = crate::common::exclusive_group(module_path!());
    let file = lagged_scene();
    let mut common = CommonParams::default();
    common.model.scene_file = file.display().to_string();
    let params = NodeParams {
        common,
        node: PredictionParams::default(),
    };
    let robot = Robot::load(&params.common).unwrap();
    let scene: Scene = robot.scene().clone();
    let mut node = PredictionNode::new(robot, params, NodeLog::new("lag")).unwrap();

    let closed_form = SPEED * (1.0 - TAU_S * (1.0 - (-1.0 / TAU_S).exp()));
    let from_rest = travel(&mut node, &scene.q0, &scene.v0);
    let mut rolling = scene.v0.clone();
    rolling[scene.model.v_index("root_joint:vx_local").unwrap()] = SPEED;
    for wheel in ["left_wheel_joint", "right_wheel_joint"] {
        rolling[scene.model.v_index(wheel).unwrap()] = SPEED / RADIUS;
    }
    let moving = travel(&mut node, &scene.q0, &rolling);
    println!(
        "a_requested_prediction_starts_the_lag_at_the_wheels_speeds: from rest (predict, \
         rollouts) {from_rest:?} m against the closed form {closed_form:.6}; rolling {moving:?} m"
    );
    for x in from_rest {
        assert!(
            (x - closed_form).abs() < 5e-4,
            "{x} m against {closed_form}"
        );
    }
    for x in moving {
        assert!((x - SPEED).abs() < 5e-4, "{x} m against {SPEED}");
    }
    std::fs::remove_dir_all(file.parent().unwrap()).ok();
}
