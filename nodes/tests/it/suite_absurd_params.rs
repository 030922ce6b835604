//! Absurd parameters at run time: `horizon 1e9` on the predictor and `max_horizon
//! 1e9` on the prediction service, set through the standard parameter services as
//! `ros2 param set` does, are refused with the parameter and its range named; a horizon within
//! the static range but beyond the scene's work limits is refused naming those limits; the
//! predictions keep flowing with the old horizon. Then, with both workers in the middle of a
//! long prediction (the predictor at a 1000 s horizon, a 1000 s `~/predict` with forces),
//! SIGINT stops the suite in under a second.

use crate::common;

use std::collections::BTreeSet;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use common::*;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{Predict, PredictRequest};
use constraint_dynamics_nodes::msg::nav_msgs::Path;
use constraint_dynamics_nodes::msg::rcl_interfaces::SetParameters;
use ros2_client::ParameterValue;

const TEST: &str = "absurd_parameters_are_refused_and_sigint_stops_a_busy_suite";

/// The predicted time span of a path [s] (its last pose's stamp minus its first's).
fn span(p: &Path) -> f64 {
    match (p.poses.first(), p.poses.last()) {
        (Some(a), Some(b)) => b.header.stamp.to_secs() - a.header.stamp.to_secs(),
        _ => 0.0,
    }
}

/// How long after a window its last paths may still arrive.
const GRACE: Duration = Duration::from_millis(500);

/// The wall clock in nanoseconds since the epoch: the suite's ROS clock (no `use_sim_time`).
fn wall_ns() -> i64 {
    let d = SystemTime::now().duration_since(UNIX_EPOCH).unwrap();
    d.as_nanos() as i64
}

/// Predictions made per second over the next `window`: the distinct paths stamped (the
/// predictor's tick time) inside it, received before it ends + [`GRACE`]; each checked to span
/// the scene's 1 s horizon. Counting arrivals instead counted what the DDS layer delivered late
/// (a CI run: 17.7 Hz "before" with 10 Hz asked and no catch-up ticks, then 6.7 Hz).
fn prediction_rate(paths: &ros2_client::Subscription<Path>, window: Duration) -> f64 {
    let from = wall_ns();
    let to = from + window.as_nanos() as i64;
    let end = Instant::now() + window + GRACE;
    let mut stamps = BTreeSet::new();
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        if let Some(Ok((p, _))) = block_on_timeout(left, paths.async_take()) {
            assert!(
                (span(&p) - 1.0).abs() < 1e-6,
                "a path spans {} s, not 1 s",
                span(&p)
            );
            let at = p.header.stamp.to_nanos();
            if (from..to).contains(&at) {
                stamps.insert(at);
            }
        }
    }
    stamps.len() as f64 / window.as_secs_f64()
}

#[test]
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn absurd_parameters_are_refused_and_sigint_stops_a_busy_suite() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let mut t = TestNode::new("cd_absurd_params_test");
    let paths = t.subscribe::<Path>("/cd_predictor/predicted_path");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &["--ros-args", "--params-file", "params/default.yaml"],
        "absurd_params",
    );
    take_until(&paths, WAIT, |_| Ok(())).expect("no predicted_path from the suite");
    let predictor = t.client::<SetParameters>("/cd_predictor/set_parameters");
    let prediction = t.client::<SetParameters>("/cd_prediction/set_parameters");
    let before = prediction_rate(&paths, Duration::from_secs(3));

    // ---- refused, with the parameter and its range named ---------------------------------------
    let cases = [
        (
            &predictor,
            "horizon",
            1e9,
            "horizon = 1e9 s is outside its range [0, 3600] s",
        ),
        (
            &predictor,
            "horizon",
            1e308,
            "horizon = 1e308 s is outside its range [0, 3600] s",
        ),
        (
            &predictor,
            "horizon",
            f64::INFINITY,
            "horizon = inf s is outside its range",
        ),
        // Within the static range, beyond the scene's: 10 Hz × horizon / 20 ms ≤ 1e6 steps per
        // second, and horizon / 20 ms ≤ 1e5 samples.
        (
            &predictor,
            "horizon",
            3000.0,
            "horizon = 3000 s is beyond its limit of 2000 s on this scene",
        ),
        (
            &prediction,
            "max_horizon",
            1e9,
            "max_horizon = 1e9 s is outside its range [0.001, 3600] s",
        ),
        // One prediction may take 1e5 samples of 20 ms.
        (
            &prediction,
            "max_horizon",
            3000.0,
            "max_horizon = 3000 s is beyond its limit of 2000 s",
        ),
    ];
    for (client, name, value, needle) in cases {
        let started = Instant::now();
        let (ok, reason) = set_param(client, name, ParameterValue::Double(value));
        assert!(!ok, "{name} = {value:e} accepted");
        assert!(reason.contains(needle), "{name} = {value:e}: {reason}");
        println!(
            "{TEST}: {name} = {value:e} refused in {:.1} ms: \"{reason}\"",
            started.elapsed().as_secs_f64() * 1e3
        );
    }

    // ---- predictions keep flowing with the scene's 1 s horizon ----------------------------------
    // Every path of a 3 s window after the refusals covers 1 s (the horizon was kept), at a
    // rate of the same order as a window before them (10 Hz asked; the CPU sets the rate:
    // compared, not assumed). An absurd horizon accepted would stop the paths (0 Hz); the
    // predictor's own rate at these defaults swings between 4.7 and 8.3 Hz on a 2-core VM
    // (one run measured 8.3 Hz before the refusals and 4.7 after, 0.57), so the bar is 0.4.
    let after = prediction_rate(&paths, Duration::from_secs(3));
    println!(
        "{TEST}: predictions {before:.1} Hz before the refusals, {after:.1} Hz after, each 1 s"
    );
    // params/default.yaml asks the predictor for 10 Hz.
    assert!(
        after >= 0.4 * before.min(10.0) && after > 1.0,
        "predictions stopped or slowed after the refusals: {after:.1} Hz (before {before:.1} Hz)"
    );

    // ---- SIGINT while both workers compute ---------------------------------------------------
    // A 1000 s horizon on the predictor (seconds per prediction, within its 2000 s limit), and
    // a 1000 s ~/predict with forces on the prediction node (its `max_horizon` raised from 10 s:
    // with the suite scene on ROS2 at 20 ms a 100 s one takes about the 0.6 s waited below).
    let (ok, reason) = set_param(&predictor, "horizon", ParameterValue::Double(1000.0));
    assert!(ok, "horizon = 1000 s refused: {reason}");
    let (ok, reason) = set_param(&prediction, "max_horizon", ParameterValue::Double(1000.0));
    assert!(ok, "max_horizon = 1000 s refused: {reason}");
    let predict = t.client::<Predict>("/cd_prediction/predict");
    let request = PredictRequest {
        use_latest_state: true,
        commands: vec![twist(0.3, 0.2)],
        horizon: 1000.0,
        with_forces: true,
        ..Default::default()
    };
    // Its reply never comes (the suite stops first); the thread ends with the test.
    std::thread::spawn(move || {
        block_on_timeout(Duration::from_secs(15), predict.async_call_service(request))
    });
    std::thread::sleep(Duration::from_millis(600));
    // No 1000 s path yet: the predictor is inside its first long prediction.
    while let Some(Ok((p, _))) = block_on_timeout(Duration::from_millis(1), paths.async_take()) {
        assert!(
            span(&p) < 2.0,
            "a 1000 s prediction finished within 0.6 s: cannot test"
        );
    }
    let (stopped, success) = suite.interrupt_timed(Duration::from_secs(10));
    let log = suite.log();
    let stopped = stopped.unwrap_or_else(|| panic!("SIGINT: still running after 10 s:\n{log}"));
    println!(
        "{TEST}: SIGINT with both workers computing: exited in {:.0} ms",
        stopped.as_secs_f64() * 1e3
    );
    assert!(success, "the suite did not exit cleanly on SIGINT:\n{log}");
    assert!(
        stopped < Duration::from_secs(1),
        "SIGINT took {stopped:?} (limit 1 s):\n{log}"
    );
    // Both were computing when the signal came (otherwise the test proves nothing).
    for node in ["cd_predictor", "cd_prediction"] {
        assert!(
            log.lines()
                .any(|l| l.contains(node) && l.contains("stopping while a computation runs")),
            "{node} was not computing at SIGINT:\n{log}"
        );
    }
    assert!(!log.contains("panicked"), "{log}");
}
