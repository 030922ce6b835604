//! The suite against a real ROS 2 peer: rclpy with rmw_fastrtps_cpp
//! (`nodes/tests/peers/suite_peer.py`) reads the predictor's three topics, calls the three
//! services and the parameter services the way `ros2 param list/get/set` does. The service
//! responses rclpy decodes must equal, field by field, what ros2-client decodes for the same
//! requests (stamps aside), so every hand-written message layout is checked against a real
//! peer.
//!
//! Needs root (a loopback-only network namespace) and the peer venv
//! (`tools/ros2/setup_peer_venv.sh`; `CD_ROS2_VENV`, default `<repo>/.venv-ros2`): `#[ignore]`d
//! in a plain `cargo test`, run by `tools/test.sh`; a missing prerequisite fails the test.

use crate::common;

use std::time::Duration;

use common::*;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesRequest, Predict, PredictRequest, ProjectVelocity,
    ProjectVelocityRequest,
};
use serde_json::Value;

const TEST: &str = "rclpy_peer_reads_topics_calls_services_and_parameters";

/// Drops every `stamp` (they are "now" for requests at a given state).
fn without_stamps(v: &mut Value) {
    match v {
        Value::Object(m) => {
            m.remove("stamp");
            m.values_mut().for_each(without_stamps);
        }
        Value::Array(a) => a.iter_mut().for_each(without_stamps),
        _ => {}
    }
}

#[test]
#[ignore = "needs root and the peer venv: run by tools/test.sh"]
fn rclpy_peer_reads_topics_calls_services_and_parameters() {
    let _group = crate::common::exclusive_group(module_path!());
    let python = peer_python(TEST);
    if !in_namespace_or_reexec(TEST) {
        return; // the run inside the namespace passed
    }
    let mut t = TestNode::new("cd_peer_test");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &["--ros-args", "--params-file", "params/default.yaml"],
        "peer",
    );
    let q = vec![0.4, -0.2, 0.9, 0.3, -0.6, 0.1, 0.5, 1.1, 0.2];
    let v = vec![0.25, 0.0, -0.3, 6.02, 3.98, 0.2, -0.1, 0.0, 0.3];
    let forces_req = GetConstraintForcesRequest {
        use_latest_state: false,
        q: q.clone(),
        v: v.clone(),
        tau: vec![0.0, 0.0, 0.0, 0.2, -0.1, 1.0, 2.0, 0.5, 0.1],
        ..Default::default()
    };
    let project_req = ProjectVelocityRequest {
        use_latest_state: false,
        q: q.clone(),
        use_twist: true,
        base_twist: twist(0.3, 0.2),
        joint_names: vec!["arm_elbow".into()],
        joint_velocities: vec![0.1],
        bound_names: vec!["right_wheel_joint".into()],
        lower: vec![-5.0],
        upper: vec![5.0],
        ..Default::default()
    };
    let predict_req = PredictRequest {
        use_latest_state: false,
        q: q.clone(),
        v: v.clone(),
        commands: vec![twist(0.3, 0.2), twist(0.1, -0.4)],
        command_period: 0.25,
        horizon: 0.5,
        with_forces: true,
        with_covariance: true,
        // Diagonal: σ = 0.01 … 0.18 over [δq; δv] (n = 2 nv = 18).
        start_covariance: (0..18 * 18)
            .map(|k| match (k / 18, k % 18) {
                (i, j) if i == j => (0.01 * (i as f64 + 1.0)).powi(2),
                _ => 0.0,
            })
            .collect(),
    };
    let forces = t.client::<GetConstraintForces>("/cd_forces/get_constraint_forces");
    let project = t.client::<ProjectVelocity>("/cd_projection/project_velocity");
    let predict = t.client::<Predict>("/cd_prediction/predict");
    let ours = [
        (
            "forces",
            serde_json::to_value(call(&forces, forces_req.clone())).unwrap(),
        ),
        (
            "project",
            serde_json::to_value(call(&project, project_req.clone())).unwrap(),
        ),
        (
            "predict",
            serde_json::to_value(call(&predict, predict_req.clone())).unwrap(),
        ),
    ];
    let requests = serde_json::json!({
        "forces": forces_req,
        "project": project_req,
        "predict": predict_req,
    });

    // The output is larger than a pipe buffer: read it while the peer runs.
    let out: Value = peer_report(
        &python,
        "suite_peer.py",
        &[requests.to_string()],
        Duration::from_secs(120),
    );
    assert_eq!(out["ok"], true, "suite_peer.py: {}", out["errors"]);

    for (key, mut mine) in ours {
        let mut theirs = out[key].clone();
        without_stamps(&mut mine);
        without_stamps(&mut theirs);
        if key == "predict" {
            // The message reports the computing time of each call.
            mine["message"] = Value::Null;
            theirs["message"] = Value::Null;
        }
        assert_eq!(mine["success"], true, "{key}: {}", mine["message"]);
        if key == "predict" {
            // A covariance per sample, n = 2 nv = 18, decoded by rclpy too (compared below).
            let samples = mine["times"].as_array().unwrap().len();
            assert_eq!(mine["covariance_dimension"], 18);
            assert_eq!(
                mine["covariances"].as_array().unwrap().len(),
                samples * 18 * 18
            );
        }
        assert_eq!(
            theirs, mine,
            "{key}: the response rclpy decoded differs from ros2-client's"
        );
    }
    let topics = &out["topics"];
    assert_eq!(topics["odom"]["header"]["frame_id"], "odom");
    assert_eq!(topics["odom"]["child_frame_id"], "base_footprint");
    assert!(topics["odom"]["pose"]["covariance"][0].as_f64().unwrap() > 0.0);
    assert!(!topics["path"]["poses"].as_array().unwrap().is_empty());
    assert_eq!(
        topics["forces"]["constraints"].as_array().unwrap().len(),
        2,
        "{}",
        topics["forces"]
    );

    let names: Vec<&str> = out["parameter_names"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    for n in [
        "rate",
        "horizon",
        "model.scene_file",
        "slip.friction_coefficient",
    ] {
        assert!(names.contains(&n), "{n} not listed by rclpy: {names:?}");
    }
    let p = &out["parameters"];
    assert_eq!(p[0]["type"], 3, "rate is a double: {p}");
    assert_eq!(p[0]["double_value"], 10.0);
    assert!(
        p[1]["string_value"]
            .as_str()
            .unwrap()
            .ends_with("suite_mobile_manipulator.yaml")
    );
    assert_eq!(p[2]["string_value"], "hold");
    assert_eq!(out["set_rate"]["successful"], false);
    assert!(
        out["set_rate"]["reason"]
            .as_str()
            .unwrap()
            .contains("cannot change")
    );
    assert_eq!(out["set_mu"]["successful"], true, "{}", out["set_mu"]);
    assert_eq!(out["mu_after"], 0.5);
    println!(
        "{TEST}: rclpy decoded the three topics; forces, projection and predict responses equal \
         ros2-client's; list/get/set parameters work ({} parameters; set rate refused: {})",
        names.len(),
        out["set_rate"]["reason"]
    );
    assert!(suite.stop(), "{}", suite.log());
}
