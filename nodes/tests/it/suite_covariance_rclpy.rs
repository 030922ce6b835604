//! Predictions a planner can trust, through the suite and a real ROS 2 peer: rclpy
//! (`nodes/tests/peers/covariance_peer.py`, rmw_fastrtps_cpp) publishes the diff drive's
//! odometry with σ_xy = 0.1 m, σ_yaw = 0.05 rad while it drives at (0.5 m/s, 0.4 rad/s), and
//! reads `predicted_odom`, `~/predict` with covariances and `/diagnostics`:
//! - every predicted odometry of a window: pose covariance = the unicycle's closed form
//!   Φ Σ₀ Φᵀ at the horizon (plus the floors), variances ≥ the start's;
//! - `~/predict`: every sample's covariance (base frame, turned to odom by the peer) = Φ(t) Σ₀
//!   Φ(t)ᵀ, growing with t;
//! - stale input (`state.stale_behaviour: stop`): no prediction started later than
//!   `state.timeout` after the last input, a WARN on `/diagnostics`; recovery when the input
//!   returns; then `warn` (set at run time): predictions go on with a WARN.
//!
//! Needs root and the peer venv (built from this tree's interface package, `CD_ROS2_VENV`):
//! `#[ignore]`d in a plain `cargo test`, run by `tools/test.sh`; a missing prerequisite fails
//! the test.

use crate::common;

use std::time::Duration;

use common::*;
use serde_json::Value;

const TEST: &str = "rclpy_odometry_covariance_is_propagated_and_stale_input_handled";

#[test]
#[ignore = "needs root and the peer venv: run by tools/test.sh"]
fn rclpy_odometry_covariance_is_propagated_and_stale_input_handled() {
    let _group = crate::common::exclusive_group(module_path!());
    let python = peer_python(TEST);
    if !in_namespace_or_reexec(TEST) {
        return; // the run inside the namespace passed
    }
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            "model.scene_file:=params/suite_diff_drive.yaml",
            "-p",
            "cd_predictor:horizon:=1.0",
            "-p",
            "cd_predictor:rate:=10.0",
            "-p",
            "state.timeout:=0.5",
        ],
        "covariance_rclpy",
    );
    let report: Value = peer_report(&python, "covariance_peer.py", &[], Duration::from_secs(120));
    if let Some(figures) = report["figures"].as_object() {
        for (k, v) in figures {
            println!("{TEST}: achieved {k}: {v}");
        }
    }
    assert_eq!(
        report["ok"],
        true,
        "covariance_peer.py: {:#}\n{}",
        report["errors"],
        suite.log()
    );
    let log = suite.log();
    for line in ["stale", "state inputs fresh again"] {
        assert!(log.contains(line), "no {line:?} in the suite's log:\n{log}");
    }
    assert!(
        suite.stop(),
        "the suite did not stop cleanly:\n{}",
        suite.log()
    );
}
