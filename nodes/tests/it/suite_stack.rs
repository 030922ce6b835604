//! The suite inside a robot stack, with a Rust "simulator" as the rest of the stack: the suite in
//! `/robot1` with `use_sim_time` and `params/namespaced.yaml`; the simulator publishes `/clock`
//! (sim time starting at 1000 s, far from wall time), `/robot1/odom`, `/robot1/joint_states`
//! and `/robot1/cmd_vel` (TwistStamped, as Nav2 and ros2_control send it). Checked:
//! - the predictor follows the command (predicted forward speed near the commanded 0.3 m/s)
//!   and stamps its odometry on the sim clock: stamp = sim time + horizon (1 s), in the
//!   namespaced frame `robot1/odom`;
//! - `/diagnostics` carries a status per node named by its fully qualified name, the predictor's
//!   OK while odometry flows, then WARN naming `odom` once odometry stops (input_timeout 1 s
//!   of sim time), while `/clock` goes on; odometry returns (predictions stopped meanwhile:
//!   `state.stale_behaviour: stop`) and the predictor follows again;
//! - the TwistStamped publisher replaced by a Twist one (0.5 m/s): the predictor switches type
//!   (graph) and follows; a RustDDS TwistStamped publisher (0.3 m/s) added beside: the predictor
//!   keeps Twist, drops that writer's messages by its announced type (RustDDS matches readers
//!   and writers of different types, so they would decode as wrong Twists) and still follows
//!   0.5 m/s.

use crate::common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::time::Duration;

use common::*;
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use constraint_dynamics_nodes::msg::geometry_msgs::{Twist, TwistStamped};
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::msg::rosgraph_msgs::Clock;
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::ros::context::qos;
use ros2_client::Publisher;

const TEST: &str = "suite_in_a_namespace_on_sim_time_reports_diagnostics";
/// Sim time at the start [ns].
const T0: i64 = 1_000_000_000_000;

#[test]
fn suite_in_a_namespace_on_sim_time_reports_diagnostics() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let mut t = TestNode::new("fake_simulator");
    let clock_pub: Publisher<Clock> = t.node.publisher("/clock", &qos::reliable(10)).unwrap();
    let odom_pub: Publisher<Odometry> = t
        .node
        .publisher("/robot1/odom", &qos::reliable(10))
        .unwrap();
    let js_pub: Publisher<JointState> = t
        .node
        .publisher("/robot1/joint_states", &qos::reliable(10))
        .unwrap();
    let cmd_pub: Publisher<TwistStamped> = t
        .node
        .publisher("/robot1/cmd_vel", &qos::reliable(10))
        .unwrap();
    let odom_sub = t.subscribe::<Odometry>("/robot1/cd_predictor/predicted_odom");
    let diag_sub = t.subscribe::<DiagnosticArray>("/diagnostics");

    // The simulator: sim time runs at real speed from T0; 100 Hz clock, 50 Hz state.
    let sim_now = Arc::new(AtomicI64::new(T0));
    let odom_on = Arc::new(AtomicBool::new(true));
    let (now, on) = (sim_now.clone(), odom_on.clone());
    let _sim = t.node.spawn(async move {
        for k in 0i64.. {
            let stamp = Time::from_nanos(T0 + k * 10_000_000);
            now.store(stamp.to_nanos(), Ordering::SeqCst);
            let _ = clock_pub.async_publish(Clock { clock: stamp }).await;
            if k % 2 == 0 {
                if on.load(Ordering::SeqCst) {
                    let mut od = Odometry::default();
                    od.header.stamp = stamp;
                    od.header.frame_id = "robot1/odom".into();
                    od.child_frame_id = "robot1/base_footprint".into();
                    od.pose.pose.orientation.w = 1.0;
                    od.twist.twist = twist(0.3, 0.0);
                    let _ = odom_pub.async_publish(od).await;
                }
                let mut js = JointState {
                    name: vec!["left_wheel_joint".into(), "right_wheel_joint".into()],
                    position: vec![0.0, 0.0],
                    ..Default::default()
                };
                js.header.stamp = stamp;
                let _ = js_pub.async_publish(js).await;
            }
            smol::Timer::after(Duration::from_millis(10)).await;
        }
    });

    // The command, TwistStamped (Nav2), 50 Hz, in a task of its own: dropping it removes the
    // writer from the graph.
    let stamped_commands = |cmd_pub: Publisher<TwistStamped>, now: Arc<AtomicI64>, v: f64| async move {
        loop {
            let mut cmd = TwistStamped {
                twist: twist(v, 0.0),
                ..Default::default()
            };
            cmd.header.stamp = Time::from_nanos(now.load(Ordering::SeqCst));
            let _ = cmd_pub.async_publish(cmd).await;
            smol::Timer::after(Duration::from_millis(20)).await;
        }
    };
    let cmd_task = t
        .node
        .spawn(stamped_commands(cmd_pub, sim_now.clone(), 0.3));

    // The predictor at 5 Hz instead of the file's 10: a 1 s prediction (dopri5 then) with its error
    // estimate and covariance kept a test build at 7.2 Hz on a 2-core VM (WARN below 9 Hz, and
    // the OK status this test waits for never came); the rate's own WARN is not what is tested.
    let rate_file = std::env::temp_dir().join(format!("cd_stack_rate_{}.yaml", std::process::id()));
    std::fs::write(
        &rate_file,
        "/robot1/cd_predictor:\n  ros__parameters:\n    rate: 5.0\n",
    )
    .expect("rate override file");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--ros-args",
            "-r",
            "__ns:=/robot1",
            "--params-file",
            "params/namespaced.yaml",
            "--params-file",
            rate_file.to_str().unwrap(),
            "-p",
            "use_sim_time:=true",
        ],
        "stack",
    );

    // Predicted odometry on the sim clock, following the command.
    let odom = take_until(&odom_sub, WAIT, |m: &Odometry| {
        let sim = sim_now.load(Ordering::SeqCst);
        let stamp = m.header.stamp.to_nanos();
        // stamp = (sim time of the tick) + horizon; the tick is at most a few 10 ms old.
        let lag = (sim + 1_000_000_000 - stamp) as f64 * 1e-9;
        if !(-0.05..=0.5).contains(&lag) {
            return Err(format!("stamp {stamp} vs sim {sim}: lag {lag} s"));
        }
        if m.header.frame_id != "robot1/odom" {
            return Err(format!("frame {}", m.header.frame_id));
        }
        let v = m.twist.twist.linear.x;
        if (v - 0.3).abs() > 0.02 {
            return Err(format!("predicted forward speed {v}"));
        }
        Ok(())
    })
    .unwrap_or_else(|e| {
        panic!(
            "predicted_odom never followed the command on sim time: {e}\n{}",
            suite.log()
        )
    });
    println!(
        "{TEST}: predicted_odom on sim time: stamp {} s, v = {:.4} m/s",
        odom.header.stamp.to_secs(),
        odom.twist.twist.linear.x
    );
    // Read at start-up: the suite publishes only after parsing its arguments.
    let _ = std::fs::remove_file(&rate_file);

    // A status per node, the predictor OK.
    let names = [
        "cd_predictor",
        "cd_forces",
        "cd_projection",
        "cd_prediction",
    ]
    .map(|n| format!("/robot1/{n}"));
    let mut seen = std::collections::BTreeMap::new();
    take_until(&diag_sub, WAIT, |m: &DiagnosticArray| {
        for s in &m.status {
            seen.insert(s.name.clone(), s.clone());
        }
        let predictor_ok = seen
            .get(&names[0])
            .is_some_and(|s| s.level == DiagnosticStatus::OK);
        if names.iter().all(|n| seen.contains_key(n)) && predictor_ok {
            Ok(())
        } else {
            Err(format!(
                "statuses so far: {:?}",
                seen.values()
                    .map(|s| (&s.name, s.level, &s.message))
                    .collect::<Vec<_>>()
            ))
        }
    })
    .unwrap_or_else(|e| panic!("no OK status for every node: {e}"));
    let p = &seen[&names[0]];
    assert_eq!(p.hardware_id, "mobile_manipulator");
    for key in [
        "achieved rate [Hz]",
        "compute p50 [ms]",
        "odom age [s]",
        "slipping contacts",
    ] {
        assert!(
            p.values.iter().any(|v| v.key == key),
            "{key} missing: {:?}",
            p.values
        );
    }
    println!("{TEST}: /diagnostics: {} OK: {:?}", p.name, p.values);

    // Odometry stops; the clock goes on: WARN naming odom.
    odom_on.store(false, Ordering::SeqCst);
    let warn = take_until(&diag_sub, WAIT, |m: &DiagnosticArray| {
        match m.status.iter().find(|s| s.name == names[0]) {
            Some(s) if s.level == DiagnosticStatus::WARN && s.message.contains("odom stale") => {
                Ok(())
            }
            Some(s) => Err(format!("{} {}", s.level, s.message)),
            None => Err("other node".into()),
        }
    })
    .unwrap_or_else(|e| panic!("no WARN after odometry stopped: {e}"));
    println!(
        "{TEST}: odometry stopped → WARN \"{}\"",
        warn.status[0].message
    );
    // Odometry returns: the predictor, stopped by `state.stale_behaviour: stop`, resumes (the
    // checks below need its predictions).
    odom_on.store(true, Ordering::SeqCst);

    // The command publisher is replaced by a plain Twist one (0.5 m/s): the predictor switches.
    drop(cmd_task);
    let twist_pub: Publisher<Twist> = t
        .node
        .publisher("/robot1/cmd_vel", &qos::reliable(10))
        .unwrap();
    let _twist_task = t.node.spawn(async move {
        loop {
            let _ = twist_pub.async_publish(twist(0.5, 0.0)).await;
            smol::Timer::after(Duration::from_millis(20)).await;
        }
    });
    let wait_log = |suite: &SuiteProcess, line: &str| {
        let deadline = std::time::Instant::now() + WAIT;
        while !suite.log().contains(line) && std::time::Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(50));
        }
        assert!(
            suite.log().contains(line),
            "no {line:?} in:\n{}",
            suite.log()
        );
    };
    wait_log(
        &suite,
        "command input /robot1/cmd_vel: geometry_msgs/msg/Twist (published as",
    );
    follows(&odom_sub, &sim_now, 0.5, "a Twist publisher");
    // A RustDDS TwistStamped publisher beside (both types published: the predictor keeps
    // Twist). RustDDS matches it with the Twist reader, which would decode its bytes as a
    // wrong Twist: its messages are dropped by the writer's announced type.
    let cmd_pub2: Publisher<TwistStamped> = t
        .node
        .publisher("/robot1/cmd_vel", &qos::reliable(10))
        .unwrap();
    let _stamped_again = t
        .node
        .spawn(stamped_commands(cmd_pub2, sim_now.clone(), 0.3));
    wait_log(
        &suite,
        "command input: ignoring a publisher of geometry_msgs::msg::dds_::TwistStamped_ \
         while following geometry_msgs/msg/Twist",
    );
    follows(&odom_sub, &sim_now, 0.5, "TwistStamped bytes beside");
    assert!(
        suite.stop(),
        "the suite did not stop cleanly:\n{}",
        suite.log()
    );
}

/// Ten predictions started after now + 1 s (sim time) all follow forward speed `v` [m/s].
fn follows(
    odom_sub: &ros2_client::Subscription<Odometry>,
    sim_now: &AtomicI64,
    v: f64,
    what: &str,
) {
    let from = sim_now.load(Ordering::SeqCst) + 2_000_000_000; // + 1 s settling + 1 s horizon
    let mut seen = 0;
    take_until(odom_sub, WAIT, |m: &Odometry| {
        if m.header.stamp.to_nanos() < from {
            return Err("older".into());
        }
        let got = m.twist.twist.linear.x;
        assert!(
            (got - v).abs() <= 0.02,
            "{what}: predicted v {got}, commanded {v}"
        );
        seen += 1;
        if seen >= 10 {
            Ok(())
        } else {
            Err(format!("{seen} so far"))
        }
    })
    .unwrap_or_else(|e| panic!("{what}: {e}"));
    println!("{TEST}: {what}: 10 predictions at {v} m/s");
}
