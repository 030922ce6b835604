//! The suite's state inputs: its four nodes share one DDS reader per state topic
//! (`/joint_states`, `/odom`), a node stays fed when the node whose ROS node holds the reader
//! is cleaned up, and a worker that only answers requests is not woken by each message (its
//! thread's context switches, read from /proc, stay far below the messages fed).

use std::time::{Duration, Instant};

use crate::common;
use crate::suite_fixture;

use common::*;
use constraint_dynamics_nodes::msg::diagnostic_msgs::DiagnosticArray;
use constraint_dynamics_nodes::msg::lifecycle_msgs::{ChangeState, ChangeStateRequest, Transition};
use constraint_dynamics_nodes::msg::nav_msgs::Path;
use suite_fixture::*;

const TEST: &str = "the_nodes_share_one_reader_per_state_topic";

/// The readers of `topic` the test's participant discovered, once `want` is reached (or the
/// count when the wait ends).
fn readers(t: &TestNode, topic: &str, want: usize) -> usize {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let n = t.node.node.subscription_count(topic);
        if n == want || Instant::now() > deadline {
            return n;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Voluntary context switches of the suite's thread whose name starts with `thread`.
fn switches(pid: u32, thread: &str) -> u64 {
    let tasks = std::fs::read_dir(format!("/proc/{pid}/task")).expect("tasks");
    for task in tasks.flatten() {
        let comm = std::fs::read_to_string(task.path().join("comm")).unwrap_or_default();
        if !comm.trim_end().starts_with(thread) {
            continue;
        }
        let status = std::fs::read_to_string(task.path().join("status")).expect("status");
        return (status.lines())
            .find_map(|l| l.strip_prefix("voluntary_ctxt_switches:"))
            .and_then(|v| v.trim().parse().ok())
            .expect("voluntary_ctxt_switches");
    }
    panic!("no thread {thread} in the suite");
}

#[test]
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn the_nodes_share_one_reader_per_state_topic() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let mut t = TestNode::new("cd_test_fanout");
    // Joint states and odometry at 50 Hz each.
    let Fixture { feed: _feed, .. } = Fixture::new(&mut t);
    let paths = t.subscribe::<Path>("/cd_predictor/predicted_path");
    let diagnostics = t.subscribe::<DiagnosticArray>("/diagnostics");
    let suite = spawn_suite("fanout");
    take_until(&paths, WAIT, |_| Ok(())).expect("no predicted_path from the suite");
    for topic in ["/joint_states", "/odom"] {
        assert_eq!(readers(&t, topic, 1), 1, "readers of {topic}");
    }

    // The idle workers (forces, projection, prediction answer requests only): 3 s of feed
    // is ~300 messages; they wake for their status (1 s) and a batch of the inbox.
    let pid = suite.child.id();
    let idle = ["cd-cd_forces", "cd-cd_projectio", "cd-cd_predictio"];
    let before: Vec<u64> = idle.iter().map(|n| switches(pid, n)).collect();
    std::thread::sleep(Duration::from_secs(3));
    for (name, before) in idle.iter().zip(before) {
        let woken = switches(pid, name) - before;
        assert!(
            woken < 40,
            "{name} woke {woken} times in 3 s of ~300 state messages"
        );
    }

    // The predictor joined first: its ROS node holds the readers. Cleaned up, the others stay
    // fed by them.
    let lifecycle = t.client::<ChangeState>("/cd_predictor/change_state");
    let transition = |id: u8, label: &str| {
        let transition = Transition {
            id,
            label: label.into(),
        };
        let ok = call(&lifecycle, ChangeStateRequest { transition }).success;
        assert!(ok, "cd_predictor: {label}");
    };
    transition(4, "deactivate");
    transition(2, "cleanup");
    let cleaned = Instant::now();
    take_until(&diagnostics, WAIT, |m: &DiagnosticArray| {
        let s = (m.status.iter().find(|s| s.name == "/cd_forces")).ok_or("another node")?;
        let age = |key: &str| {
            (s.values.iter().find(|v| v.key == key))
                .and_then(|v| v.value.parse::<f64>().ok())
                .ok_or(format!("{key}: none"))
        };
        if cleaned.elapsed() < Duration::from_secs(2) {
            return Err("too soon after the cleanup".into());
        }
        let (joints, odom) = (age("joint_states age [s]")?, age("odom age [s]")?);
        match joints < 0.5 && odom < 0.5 {
            true => Ok(()),
            false => Err(format!(
                "cd_forces: joint_states {joints} s, odom {odom} s old"
            )),
        }
    })
    .expect("cd_forces fed after the predictor's cleanup");
    for topic in ["/joint_states", "/odom"] {
        assert_eq!(
            readers(&t, topic, 1),
            1,
            "readers of {topic} after the cleanup"
        );
    }

    // Configured and active again, the predictor joins the readers and predicts.
    transition(1, "configure");
    transition(3, "activate");
    while paths.take().ok().flatten().is_some() {}
    take_until(&paths, WAIT, |_| Ok(())).expect("no predicted_path after activation");
    assert_eq!(readers(&t, "/joint_states", 1), 1);
    stop_suite(suite);
}
