//! Parameters as a ROS user meets them, through a real ROS 2 peer (rclpy with
//! rmw_fastrtps_cpp, `nodes/tests/peers/params_peer.py`), in one suite start:
//! - `-p envelope.velocity_smoother:=velocity_smoother` (a predictor parameter, given to every
//!   node as rcl gives `-p`) reaches the predictor; the other nodes ignore it and start;
//!   `-p no_such.parameter:=1`, which no node has, is one WARN naming it;
//! - `-p cd_forces:model.scene_file:=` a scene that does not exist: cd_forces stays
//!   unconfigured with an ERROR on `/diagnostics` saying why, the other three serve;
//! - the garbage payload values once accepted by `SetParameters` (`payload.com` = [NaN, 0, 0]
//!   and [0.0], `payload.inertia` = [1.0, 2.0]) are refused when set, naming the parameter and
//!   its shape, with every `payload.*` read back unchanged by `GetParameters`; a valid set
//!   afterwards succeeds; `SetParametersAtomically` is judged as a whole (a mass with its frame
//!   in one request is accepted, a valid mass with a bad inertia stores neither).
//!
//! Then the same failure with `--exit-on-failure` (one node alone) ends the process.
//!
//! Needs root (a loopback-only network namespace) and the peer venv
//! (`tools/ros2/setup_peer_venv.sh`; `CD_ROS2_VENV`, default `<repo>/.venv-ros2`): `#[ignore]`d
//! in a plain `cargo test`, run by `tools/test.sh`; a missing prerequisite fails the test.

use crate::common;

use std::time::Duration;

use common::*;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    Predict, PredictRequest, ProjectVelocity, ProjectVelocityRequest,
};
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use serde_json::{Value, json};

const TEST: &str =
    "rclpy_sets_are_checked_whole_overrides_reach_their_node_and_a_failure_stays_local";

/// lifecycle_msgs/State ids.
const UNCONFIGURED: u64 = 1;
const ACTIVE: u64 = 3;

#[test]
#[ignore = "needs root and the peer venv: run by tools/test.sh"]
fn rclpy_sets_are_checked_whole_overrides_reach_their_node_and_a_failure_stays_local() {
    let _group = crate::common::exclusive_group(module_path!());
    let python = peer_python(TEST);
    if !in_namespace_or_reexec(TEST) {
        return; // the run inside the namespace passed
    }
    let mut t = TestNode::new("cd_params_test");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            "envelope.velocity_smoother:=velocity_smoother",
            "-p",
            "no_such.parameter:=1",
            "-p",
            "cd_forces:model.scene_file:=params/no_such_scene.yaml",
            "-p",
            "covariance.propagate:=false",
        ],
        "params",
    );

    // The three healthy nodes serve.
    let odom = t.subscribe::<Odometry>("/cd_predictor/predicted_odom");
    take_until(&odom, WAIT, |_| Ok(())).unwrap_or_else(|e| {
        panic!("no predicted odometry: {e}\n{}", suite.log());
    });
    let predict = t.client::<Predict>("/cd_prediction/predict");
    let r = call(
        &predict,
        PredictRequest {
            use_latest_state: true,
            commands: vec![twist(0.2, 0.1)],
            horizon: 0.5,
            ..Default::default()
        },
    );
    assert!(r.success, "predict: {}", r.message);
    let project = t.client::<ProjectVelocity>("/cd_projection/project_velocity");
    let r = call(
        &project,
        ProjectVelocityRequest {
            use_latest_state: true,
            use_twist: true,
            base_twist: twist(0.2, 0.1),
            ..Default::default()
        },
    );
    assert!(r.success, "project_velocity: {}", r.message);

    let out = peer_report(&python, "params_peer.py", &[], Duration::from_secs(120));
    assert_eq!(out["ok"], true, "params_peer.py: {out}\n{}", suite.log());
    let zeros = |n: usize| json!(vec![0.0; n]);
    let before = json!({
        "payload.frame": "", "payload.mass": 0.0,
        "payload.com": zeros(3), "payload.inertia": zeros(6),
    });
    assert_eq!(out["before"], before, "{out}");

    // Each garbage value refused at set time, naming the parameter and its shape; nothing
    // stored.
    let needles = [
        "payload.com = [NaN, 0.0, 0.0]: entry NaN is not finite",
        "payload.com = [0.0] must be [x, y, z] [m] (3 numbers)",
        "payload.inertia = [1.0, 2.0] must be [ixx, ixy, ixz, iyy, iyz, izz] [kg·m²] (6 numbers)",
    ];
    for (r, needle) in out["garbage"].as_array().unwrap().iter().zip(needles) {
        refused(r, needle);
        assert_eq!(r["after"], before, "stored value changed: {r}");
    }
    // A valid set afterwards succeeds.
    accepted(&out["valid_frame"]);
    assert_eq!(out["valid_frame"]["after"]["payload.frame"], "base_link");
    accepted(&out["frame_cleared"]);
    // Atomically: a mass with the frame that carries it is valid as a whole.
    accepted(&out["atomic_good"]);
    let good = &out["atomic_good"]["after"];
    assert_eq!(
        (&good["payload.mass"], &good["payload.frame"]),
        (&json!(1.5), &json!("tool0"))
    );
    assert_eq!(out["predictor_payload"], "1.5 kg on tool0", "{out}");
    // A valid member of a refused request is not stored either.
    refused(&out["atomic_bad"], "payload.inertia = [1.0, 2.0] must be");
    assert_eq!(out["atomic_bad"]["after"], *good, "{out}");

    // The predictor-only override: on the predictor, absent elsewhere.
    let vs = &out["velocity_smoother"];
    assert_eq!(vs["cd_predictor"], "velocity_smoother", "{vs}");
    for n in ["cd_forces", "cd_projection", "cd_prediction"] {
        assert_eq!(vs[n], json!({"not_set": true}), "{n}: {vs}");
    }
    // One node's failed configuration stays local.
    let states = &out["states"];
    for (n, want) in [
        ("cd_predictor", ACTIVE),
        ("cd_forces", UNCONFIGURED),
        ("cd_projection", ACTIVE),
        ("cd_prediction", ACTIVE),
    ] {
        assert_eq!(states[n], want, "{n}: {states}");
    }
    let status = &out["forces_status"];
    assert_eq!(status["error"], true, "{status}");
    let message = status["message"].as_str().unwrap();
    assert!(
        message.starts_with("configure failed: ") && message.contains("no_such_scene.yaml"),
        "{message}"
    );
    assert_eq!(status["values"]["lifecycle state"], "unconfigured");
    println!("{TEST}: achieved: /cd_forces on /diagnostics: {message}");

    // Still serving after all of it.
    let r = call(
        &predict,
        PredictRequest {
            use_latest_state: true,
            commands: vec![twist(0.2, 0.1)],
            horizon: 0.5,
            ..Default::default()
        },
    );
    assert!(r.success, "predict at the end: {}", r.message);
    assert!(suite.alive(), "the suite exited:\n{}", suite.log());
    let log = suite.log();
    let warned: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("no_such.parameter"))
        .collect();
    assert!(
        warned.len() == 1 && warned[0].starts_with("[WARN]"),
        "one WARN naming no_such.parameter: {warned:?}"
    );
    assert!(!log.contains("unknown field"), "{log}");
    assert!(suite.stop(), "{}", suite.log());

    // --exit-on-failure: the same failure ends the process, naming the scene.
    let mut alone = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--node",
            "forces",
            "--exit-on-failure",
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            "model.scene_file:=params/no_such_scene.yaml",
        ],
        "params_exit",
    );
    let status = block_on_timeout(WAIT, async {
        loop {
            if let Ok(Some(s)) = alone.child.try_wait() {
                return s;
            }
            smol::Timer::after(Duration::from_millis(20)).await;
        }
    })
    .unwrap_or_else(|| panic!("still running with --exit-on-failure:\n{}", alone.log()));
    let log = alone.log();
    assert!(
        status.code() == Some(1)
            && log.contains("error: cd_forces")
            && log.contains("no_such_scene.yaml"),
        "{status}: {log}"
    );
    println!(
        "{TEST}: achieved: --exit-on-failure exited ({status}) after {:.2} s",
        alone.started.elapsed().as_secs_f64()
    );
}

fn refused(r: &Value, needle: &str) {
    assert_eq!(r["successful"], false, "accepted: {r}");
    let reason = r["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains(needle),
        "reason {reason:?} lacks {needle:?}"
    );
    println!("{TEST}: refused: \"{reason}\"");
}

fn accepted(r: &Value) {
    assert_eq!(r["successful"], true, "refused: {r}");
}
