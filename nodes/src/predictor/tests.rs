//! The predictor's logic without DDS: messages in, messages out, on the ROS clock.

use super::*;
use crate::params::CommonParams;

fn node(fallback: &str) -> PredictorNode {
    let mut common = CommonParams::default();
    common.model.scene_file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/suite_diff_drive.yaml"
    )
    .into();
    let mut params = NodeParams::<PredictorParams> {
        common,
        node: PredictorParams::default(),
    };
    params.node.command.fallback = fallback.into();
    params.node.command.timeout = 0.5;
    params.node.horizon = 1.0;
    let robot = Robot::load(&params.common).unwrap();
    PredictorNode::new(robot, params, NodeLog::new("test")).unwrap()
}

fn tick(n: &mut PredictorNode, now: Time) -> PeriodicOutput {
    let mut out = None;
    n.tick(now, &mut |o| out = Some(o)).unwrap();
    *out.expect("a tick publishes")
}

fn forward(t: &Twist) -> f64 {
    t.linear.x
}

/// A command is used while it is younger than `command.timeout` on the ROS clock, whatever the
/// wall clock does; then the fallback (stop) applies.
#[test]
fn command_timeout_runs_on_the_ros_clock() {
    let mut n = node("stop");
    let t0 = Time::from_nanos(1_000_000_000_000); // a simulation's /clock, far from wall time
    let cmd = Twist {
        linear: crate::msg::geometry_msgs::Vector3 {
            x: 0.5,
            y: 0.0,
            z: 0.0,
        },
        ..Default::default()
    };
    n.handle(PredictorInput::Command(cmd), t0, &mut |_| {});
    // 0.4 s of ROS time later: the command holds; the PI-driven base speeds up towards 0.5 m/s.
    let fresh = tick(&mut n, time_plus(t0, 0.4));
    let v_fresh = forward(&fresh.odom.twist.twist);
    assert!(
        v_fresh > 0.3 && v_fresh < 0.55,
        "v at the horizon under 0.5 m/s: {v_fresh}"
    );
    // The odometry is stamped start + horizon on the ROS clock.
    assert_eq!(
        fresh.odom.header.stamp.to_nanos(),
        time_plus(t0, 1.4).to_nanos()
    );
    // 0.6 s later (> timeout): stop, the predicted base stays at rest.
    let stale = tick(&mut n, time_plus(t0, 0.6));
    let v_stale = forward(&stale.odom.twist.twist);
    assert!(
        v_stale.abs() < 1e-9,
        "v at the horizon after the timeout: {v_stale}"
    );
}

/// The forces published at the start state: the two rolling contacts, in the odom frame, with
/// Jᵀλ per coordinate; at rest on a level floor no tangential force is needed.
#[test]
fn forces_at_rest_need_no_friction() {
    let mut n = node("stop");
    let out = tick(&mut n, Time::from_nanos(0));
    let f = &out.forces;
    assert_eq!(f.header.frame_id, "odom");
    assert_eq!(f.constraints.len(), 2);
    for c in &f.constraints {
        assert_eq!(c.kind, "rolling");
        assert!(
            c.tangential_force.abs() < 1e-9,
            "{}: {}",
            c.name,
            c.tangential_force
        );
        assert!(!c.slipping);
    }
    assert_eq!(f.generalized_force.len(), f.v_names.len());
    assert_eq!(out.path.poses.len(), 51, "1 s at 0.02 s samples, both ends");
}
