//! The velocity projection as a command filter between a planner and the base controller:
//! `cd_projection` with `filter.enabled` on the bundled differential drive
//! (`params/suite_diff_drive.yaml`, at rest). Each `Twist` on the input topic comes out on the
//! output topic as the core's projection of that base twist at the latest state (URDF wheel
//! speed limit 20 rad/s): a feasible command passes unchanged, (1 m/s, 0.5 rad/s) — right
//! wheel at 21.7 rad/s — comes out as the core's closest feasible twist.

mod common;

use std::time::Duration;

use common::*;
use constraint_dynamics::Scene;
use constraint_dynamics::System;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::projection::{ProjectionRequest, VelocityProjector, project_system};
use constraint_dynamics_nodes::msg::geometry_msgs::Twist;
use constraint_dynamics_nodes::ros::context::qos;

const TEST: &str = "filter_publishes_the_projected_command";

#[test]
fn filter_publishes_the_projected_command() {
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let scene = Scene::load(repo_root().join("params/suite_diff_drive.yaml")).unwrap();
    let mut sys = System::from_scene(&scene).unwrap();
    sys.formulation = Formulation::Multipliers;
    let mut projector = VelocityProjector::new(&sys.model, &sys.constraints);

    let mut t = TestNode::new("cd_filter_test");
    let input = t
        .node
        .publisher::<Twist>("/planner/cmd_vel", &qos::reliable(10))
        .unwrap();
    let output = t.subscribe::<Twist>("/base/cmd_vel");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--node",
            "projection",
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            "model.scene_file:=params/suite_diff_drive.yaml",
            "-p",
            "filter.enabled:=true",
            "-p",
            "filter.input_topic:=/planner/cmd_vel",
            "-p",
            "filter.output_topic:=/base/cmd_vel",
        ],
        "filter",
    );
    for (v, w) in [(0.3, 0.2), (1.0, 0.5), (-0.8, -1.5)] {
        let req = ProjectionRequest {
            base_twist: Some(vec![v, 0.0, w]),
            ..Default::default()
        };
        let expected =
            project_system(&mut projector, &mut sys, &scene.q0, &scene.v0, &req).unwrap();
        let e = expected.base_twist.clone().unwrap();
        // Send until the filter's answer to this command arrives (the first commands may go
        // out before the subscriptions have matched).
        let mut got = Err(String::from("nothing sent"));
        for _ in 0..100 {
            input.publish(twist(v, w)).unwrap();
            got = take_until(&output, Duration::from_millis(200), |m: &Twist| {
                close(
                    "filtered twist",
                    &[m.linear.x, m.linear.y, m.angular.z],
                    &e,
                    1e-9,
                )
            });
            if got.is_ok() {
                break;
            }
        }
        let got = got.unwrap_or_else(|err| panic!("({v}, {w}): {err}"));
        println!(
            "{TEST}: ({v}, {w}) → ({:.6}, {:.6}, {:.6}) = core ({})",
            got.linear.x, got.linear.y, got.angular.z, expected.message
        );
    }
    assert!(suite.stop(), "{}", suite.log());
}
