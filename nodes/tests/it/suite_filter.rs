//! The velocity projection as a command filter between a planner and the base controller:
//! `cd_projection` with `filter.enabled` on the bundled differential drive
//! (`params/suite_diff_drive.yaml`, at rest). Each `Twist` on the input topic comes out on the
//! output topic as the core's projection of that base twist at the latest state (URDF wheel
//! speed limit 20 rad/s): a feasible command passes unchanged, (1 m/s, 0.5 rad/s) — right
//! wheel at 21.7 rad/s — comes out as the core's closest feasible twist.
//!
//! Every message counts: each output is the answer to one input, and the only inputs are this
//! test's, so every output received during a case must be that case's projection (to 1e-12),
//! not just the first good one. Settling: commands sent before the node's subscription has
//! matched are lost, not answered, so the test repeats the case's command until the first
//! answer arrives (at most 100 × 200 ms), then sends 20 more (every 20 ms) and reads for a
//! further 0.5 s, so that no answer of a case is still in flight when the next case starts.
//! At least 10 answers per case are required.

use crate::common;

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
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn filter_publishes_the_projected_command() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let scene = Scene::load(repo_root().join("params/suite_diff_drive.yaml")).unwrap();
    let mut sys = System::from_scene(&scene).unwrap();
    sys = sys.with_formulation(Formulation::Multipliers);
    let mut projector = VelocityProjector::new(sys.model(), sys.constraints());

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
        // (answers so far, largest deviation from the core's twist)
        let mut seen = (0usize, 0.0f64);
        let note = |seen: &mut (usize, f64), m: &Twist| {
            let got = [m.linear.x, m.linear.y, m.angular.z];
            // The node runs the core's projection on the same numbers: achieved 0.
            close("filtered twist", &got, &e, 1e-12)
                .unwrap_or_else(|err| panic!("({v}, {w}), answer {}: {err}", seen.0));
            seen.1 = got
                .iter()
                .zip(&e)
                .fold(seen.1, |a, (x, y)| a.max((x - y).abs()));
            seen.0 += 1;
        };
        // Until the first answer: every message that arrives is checked.
        for _ in 0..100 {
            input.publish(twist(v, w)).unwrap();
            if let Some(Ok((m, _))) =
                block_on_timeout(Duration::from_millis(200), output.async_take())
            {
                note(&mut seen, &m);
                break;
            }
        }
        assert!(seen.0 > 0, "({v}, {w}): no answer to 100 commands");
        // 20 more commands, then drain: every answer checked.
        for _ in 0..20 {
            input.publish(twist(v, w)).unwrap();
            std::thread::sleep(Duration::from_millis(20));
            while let Some(Ok((m, _))) =
                block_on_timeout(Duration::from_millis(1), output.async_take())
            {
                note(&mut seen, &m);
            }
        }
        while let Some(Ok((m, _))) =
            block_on_timeout(Duration::from_millis(500), output.async_take())
        {
            note(&mut seen, &m);
        }
        let (answers, worst) = seen;
        assert!(
            answers >= 10,
            "({v}, {w}): only {answers} answers to 21+ commands"
        );
        println!(
            "{TEST}: ({v}, {w}) → ({:.6}, {:.6}, {:.6}) = core ({}); {answers} answers, all \
             within {worst:.1e} of it",
            e[0], e[1], e[2], expected.message
        );
    }
    assert!(suite.stop(), "{}", suite.log());
}
