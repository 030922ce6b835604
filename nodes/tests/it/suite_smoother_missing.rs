//! `envelope.velocity_smoother` naming a node nobody runs costs a throttled WARN, never the
//! predictor's tick: `~/acceleration_limits` keeps the predictor's rate and the bridge's
//! unanswered `get_parameters` (tried every 2 s) logs one WARN per 10 s window. With a real
//! smoother (an rclpy stand-in), see `suite_envelope_rclpy`.
//!
//! Needs root: `#[ignore]`d in a plain `cargo test`, run by `tools/test.sh`.

use crate::common;

use std::time::Duration;

use common::*;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::AccelerationLimits;

const RATE: f64 = 10.0; // params/default.yaml's cd_predictor rate [Hz]
const MISSING: &str = "a_missing_smoother_costs_one_warn_per_window_not_the_limits";

/// The limits at 10 Hz and one WARN over 7 s.
#[test]
#[ignore = "needs root: run by tools/test.sh"]
fn a_missing_smoother_costs_one_warn_per_window_not_the_limits() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(MISSING) {
        return; // the run inside the namespace passed
    }
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            "cd_predictor:covariance.propagate:=false",
            "-p",
            "cd_predictor:envelope.velocity_smoother:=no_such_smoother",
        ],
        "envelope_missing_smoother",
    );
    let mut node = TestNode::new("cd_envelope_test");
    let sub = node.subscribe::<AccelerationLimits>("/cd_predictor/acceleration_limits");
    take_until(&sub, WAIT, |_| Ok(()))
        .unwrap_or_else(|e| panic!("no limits: {e}\n{}", suite.log()));
    let start = std::time::Instant::now();
    let window = Duration::from_secs(7);
    let mut n = 0usize;
    while start.elapsed() < window {
        if let Some(Ok(_)) = block_on_timeout(Duration::from_millis(500), sub.async_take()) {
            n += 1;
        }
    }
    let rate = n as f64 / window.as_secs_f64();
    println!("{MISSING}: achieved {rate:.2} Hz of acceleration_limits with the smoother missing");
    // 10 Hz; ±1 message at the window's ends.
    assert!((rate - RATE).abs() <= 0.3, "{rate} Hz\n{}", suite.log());
    let log = suite.log();
    let warns: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("WARN") && l.contains("velocity smoother 'no_such_smoother'"))
        .collect();
    println!("{MISSING}: {} WARN line(s): {warns:?}", warns.len());
    assert_eq!(warns.len(), 1, "{log}");
    assert!(
        warns[0].contains("get_parameters: no answer"),
        "{}",
        warns[0]
    );
    assert!(
        suite.stop(),
        "the suite did not stop cleanly:\n{}",
        suite.log()
    );
}
