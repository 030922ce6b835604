//! The suite inside an rclpy robot stack: suite in `/robot1` with `use_sim_time`,
//! `params/namespaced.yaml` and `autostart: false`; `nodes/tests/peers/stack_peer.py` (rclpy,
//! rmw_fastrtps_cpp) is the simulator, the lifecycle manager and rviz2's reader:
//! - lifecycle: every node starts unconfigured with nothing but its lifecycle and parameter
//!   services; configure and activate as Nav2's lifecycle_manager does (ids, labels and
//!   `~/transition_event`s of lifecycle_msgs); deactivate removes the predictor's topics and
//!   nothing more arrives; cleanup, shutdown by label, finalized refuses activate;
//! - the predictor follows TwistStamped commands the base is not moving at, then a plain
//!   Twist publisher that replaces the stamped one (the command type follows the graph);
//!   stamps = sim time + horizon;
//! - `visualization_msgs/MarkerArray` decoded by rclpy: force arrows at the URDF's contact
//!   points, = 0.01 m/N × the `ConstraintForces` of the same stamp, red iff slipping; the
//!   footprint along the path from the odometry pose; the wheel's `WrenchStamped` in its own
//!   frame;
//! - `/diagnostics` (decoded by rclpy): every node OK, the predictor WARN when odometry stops.
//!
//! Needs root and the peer venv: `#[ignore]`d in a plain `cargo test`, run by
//! `tools/test.sh`; a missing prerequisite fails the test.

use crate::common;

use std::time::Duration;

use common::*;
use serde_json::Value;

const TEST: &str = "rclpy_stack_drives_the_lifecycle_reads_markers_and_commands";

#[test]
#[ignore = "needs root and the peer venv: run by tools/test.sh"]
fn rclpy_stack_drives_the_lifecycle_reads_markers_and_commands() {
    let _group = crate::common::exclusive_group(module_path!());
    let python = peer_python(TEST);
    if !in_namespace_or_reexec(TEST) {
        return; // the run inside the namespace passed
    }
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--ros-args",
            "-r",
            "__ns:=/robot1",
            "--params-file",
            "params/namespaced.yaml",
            "-p",
            "use_sim_time:=true",
            "-p",
            "autostart:=false",
            "-p",
            "cd_predictor:markers.wrenches:=true",
        ],
        "stack_rclpy",
    );
    let report: Value = peer_report(&python, "stack_peer.py", &[], Duration::from_secs(240));
    if let Some(figures) = report["figures"].as_object() {
        for (k, v) in figures {
            println!("{TEST}: achieved {k}: {v}");
        }
    }
    assert_eq!(
        report["ok"],
        true,
        "stack_peer.py: {:#}\n{}",
        report["errors"],
        suite.log()
    );
    let log = suite.log();
    assert!(
        log.contains("command input /robot1/cmd_vel: geometry_msgs/msg/Twist (published as"),
        "the switch to Twist is not in the log:\n{log}"
    );
    assert!(
        suite.stop(),
        "the suite did not stop cleanly:\n{}",
        suite.log()
    );
}
