//! Malformed requests and messages: every service answers `success = false` with a message
//! that names what is wrong (unknown joint name, NaN, wrong array length, impossible values),
//! a bad `/robot_description` (empty, not XML, a URDF without the scene's wheels) is refused
//! with an error on `/rosout` while the current model stays, a malformed `/joint_states` is
//! dropped — and after each, the next valid request is served. The suite never exits and
//! never panics.
//!
//! Also: one node alone (`constraint_dynamics_forces`, the `--node` binary) renamed and moved
//! with `-r __node:= -r __ns:=` and a topic remap.

use crate::common;

use std::time::Duration;

use common::*;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesRequest, Predict, PredictRequest, ProjectVelocity,
    ProjectVelocityRequest,
};
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::msg::std_msgs::StringMsg;

const TEST: &str = "malformed_requests_get_reasons_and_the_suite_keeps_serving";
const TEST_SINGLE: &str = "single_node_with_name_namespace_and_remap";

fn expect_error(what: &str, success: bool, message: &str, needles: &[&str]) {
    assert!(!success, "{what}: accepted, expected an error");
    for n in needles {
        assert!(
            message.contains(n),
            "{what}: the message does not say {n:?}: {message}"
        );
    }
    println!("{TEST}: {what} → \"{message}\"");
}

#[test]
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn malformed_requests_get_reasons_and_the_suite_keeps_serving() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let mut t = TestNode::new("cd_bad_input_test");
    let feed = FeedPublisher::start(&mut t);
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &["--ros-args", "--params-file", "params/default.yaml"],
        "bad_input",
    );
    let forces = t.client::<GetConstraintForces>("/cd_forces/get_constraint_forces");
    let project = t.client::<ProjectVelocity>("/cd_projection/project_velocity");
    let predict = t.client::<Predict>("/cd_prediction/predict");
    let good_forces = GetConstraintForcesRequest {
        use_latest_state: true,
        ..Default::default()
    };
    let good_project = ProjectVelocityRequest {
        use_latest_state: true,
        use_twist: true,
        base_twist: twist(0.2, 0.1),
        ..Default::default()
    };
    let good_predict = PredictRequest {
        use_latest_state: true,
        commands: vec![twist(0.2, 0.1)],
        horizon: 0.5,
        ..Default::default()
    };
    let serves = |label: &str| {
        let r = call(&forces, good_forces.clone());
        assert!(r.success, "after {label}: forces: {}", r.message);
        let r = call(&project, good_project.clone());
        assert!(r.success, "after {label}: projection: {}", r.message);
        let r = call(&predict, good_predict.clone());
        assert!(r.success, "after {label}: predict: {}", r.message);
    };
    serves("start");

    // ---- get_constraint_forces ------------------------------------------------------------------
    let cases: Vec<(&str, GetConstraintForcesRequest, Vec<&str>)> = vec![
        (
            "forces: unknown joint name",
            GetConstraintForcesRequest {
                q_names: vec!["no_such_joint".into()],
                q: vec![0.1],
                ..Default::default()
            },
            vec!["unknown coordinate 'no_such_joint'", "arm_elbow"],
        ),
        (
            "forces: NaN in q",
            GetConstraintForcesRequest {
                q: vec![0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                ..Default::default()
            },
            vec!["root_joint:yaw", "not finite"],
        ),
        (
            "forces: wrong q length",
            GetConstraintForcesRequest {
                q: vec![1.0, 2.0, 3.0],
                ..Default::default()
            },
            vec!["expected 9 values", "got 3"],
        ),
        (
            "forces: wrong tau length",
            GetConstraintForcesRequest {
                use_latest_state: true,
                tau: vec![1.0; 4],
                ..Default::default()
            },
            vec!["tau", "expected 9 values", "got 4"],
        ),
        (
            "forces: names and values of different lengths",
            GetConstraintForcesRequest {
                q_names: vec!["arm_elbow".into(), "arm_wrist".into()],
                q: vec![0.3],
                ..Default::default()
            },
            vec!["q_names has 2 entries but q has 1"],
        ),
        (
            "forces: empty state",
            GetConstraintForcesRequest::default(),
            vec!["q: expected 9 values", "got 0"],
        ),
    ];
    for (what, req, needles) in cases {
        let r = call(&forces, req);
        expect_error(what, r.success, &r.message, &needles);
        serves(what);
    }

    // ---- project_velocity ---------------------------------------------------------------------
    let cases: Vec<(&str, ProjectVelocityRequest, Vec<&str>)> = vec![
        (
            "projection: unknown joint name",
            ProjectVelocityRequest {
                use_latest_state: true,
                v_names: vec!["elbow".into()],
                v_des: vec![0.2],
                ..Default::default()
            },
            vec!["unknown velocity coordinate 'elbow'"],
        ),
        (
            "projection: wrong v_des length",
            ProjectVelocityRequest {
                use_latest_state: true,
                v_des: vec![0.1, 0.2],
                ..Default::default()
            },
            vec!["v_des", "expected 9", "got 2"],
        ),
        (
            "projection: NaN in the twist",
            ProjectVelocityRequest {
                use_latest_state: true,
                use_twist: true,
                base_twist: twist(f64::NAN, 0.0),
                ..Default::default()
            },
            vec!["base_twist", "not finite"],
        ),
        (
            "projection: NaN bound",
            ProjectVelocityRequest {
                use_latest_state: true,
                use_twist: true,
                base_twist: twist(0.1, 0.0),
                bound_names: vec!["vx".into()],
                lower: vec![f64::NAN],
                upper: vec![1.0],
                ..Default::default()
            },
            vec!["bounds of 'vx'", "NaN"],
        ),
        (
            "projection: bounds of different lengths",
            ProjectVelocityRequest {
                use_latest_state: true,
                use_twist: true,
                base_twist: twist(0.1, 0.0),
                bound_names: vec!["vx".into()],
                lower: vec![],
                upper: vec![1.0],
                ..Default::default()
            },
            vec!["bound_names has 1 entries but lower has 0"],
        ),
        (
            "projection: no desired velocity",
            ProjectVelocityRequest {
                use_latest_state: true,
                ..Default::default()
            },
            vec!["no desired velocity"],
        ),
    ];
    for (what, req, needles) in cases {
        let r = call(&project, req);
        expect_error(what, r.success, &r.message, &needles);
        assert_eq!(r.status, "error");
        serves(what);
    }
    // Well-formed but infeasible: success = false, status infeasible, the conflict named.
    let r = call(
        &project,
        ProjectVelocityRequest {
            use_latest_state: true,
            use_twist: true,
            base_twist: twist(0.3, 0.0),
            bound_names: vec!["left_wheel_joint".into(), "vx".into(), "wz".into()],
            lower: vec![1.0, f64::NEG_INFINITY, 0.0],
            upper: vec![f64::INFINITY, 0.0, 0.0],
            ..Default::default()
        },
    );
    assert_eq!(r.status, "infeasible", "{}", r.message);
    assert!(!r.success && !r.conflicting.is_empty() && r.v.is_empty());
    println!(
        "{TEST}: projection: infeasible bounds → status infeasible, conflicting {:?}",
        r.conflicting
    );

    // ---- predict ------------------------------------------------------------------------------
    let cases: Vec<(&str, PredictRequest, Vec<&str>)> = vec![
        (
            "predict: NaN horizon",
            PredictRequest {
                horizon: f64::NAN,
                ..good_predict.clone()
            },
            vec!["horizon", "positive and finite"],
        ),
        (
            "predict: horizon beyond max_horizon",
            PredictRequest {
                horizon: 1e6,
                ..good_predict.clone()
            },
            vec!["max_horizon"],
        ),
        (
            "predict: NaN command",
            PredictRequest {
                commands: vec![twist(0.2, f64::NAN)],
                ..good_predict.clone()
            },
            vec!["commands[0]", "non-finite"],
        ),
        (
            "predict: sideways command",
            PredictRequest {
                commands: vec![{
                    let mut t = twist(0.2, 0.0);
                    t.linear.y = 0.3;
                    t
                }],
                ..good_predict.clone()
            },
            vec!["commands[0]", "linear.x and angular.z only"],
        ),
        (
            "predict: wrong q length",
            PredictRequest {
                use_latest_state: false,
                q: vec![0.0; 5],
                ..good_predict.clone()
            },
            vec!["q: expected 9 values", "got 5"],
        ),
        (
            "predict: several commands without a period",
            PredictRequest {
                commands: vec![twist(0.1, 0.0), twist(0.2, 0.0)],
                command_period: 0.0,
                ..good_predict.clone()
            },
            vec!["command_period"],
        ),
    ];
    for (what, req, needles) in cases {
        let r = call(&predict, req);
        expect_error(what, r.success, &r.message, &needles);
        serves(what);
    }

    // ---- malformed state messages are dropped ---------------------------------------------------
    feed.set(RobotFeed {
        joint_state: Some(JointState {
            name: vec!["arm_elbow".into(), "arm_wrist".into()],
            position: vec![0.1],
            ..Default::default()
        }),
        ..Default::default()
    });
    std::thread::sleep(Duration::from_millis(300));
    feed.set(RobotFeed {
        joint_state: Some(JointState {
            name: vec!["arm_elbow".into()],
            position: vec![f64::INFINITY],
            ..Default::default()
        }),
        ..Default::default()
    });
    std::thread::sleep(Duration::from_millis(300));
    feed.set(RobotFeed::default());
    serves("malformed joint states");

    // ---- bad /robot_description ------------------------------------------------------------------
    let description = description_publisher(&mut t);
    let urdf = std::fs::read_to_string(repo_root().join("urdf/mobile_manipulator.urdf")).unwrap();
    let no_wheels = urdf.replace("\"left_wheel\"", "\"left_tyre\"");
    for (what, text, needle) in [
        ("empty URDF", String::new(), "the URDF is empty"),
        (
            "not XML",
            "<robot name=\"x\"><link".to_string(),
            "malformed XML",
        ),
        (
            "URDF without the scene's wheel",
            no_wheels,
            "left_wheel_contact",
        ),
    ] {
        description.publish(StringMsg { data: text }).unwrap();
        let log = take_until(t.rosout(), WAIT, |l: &ros2_client::Log| {
            if l.level == ros2_client::Log::ERROR
                && l.msg.contains("robot_description refused")
                && l.msg.contains(needle)
            {
                Ok(())
            } else {
                Err(format!("{}: {}", l.name, l.msg))
            }
        })
        .unwrap_or_else(|e| panic!("{what}: no error on /rosout: {e}"));
        println!(
            "{TEST}: /robot_description {what} → /rosout [{}] \"{}\"",
            log.name, log.msg
        );
        serves(what);
    }

    assert!(suite.alive(), "the suite exited:\n{}", suite.log());
    assert!(
        suite.stop(),
        "the suite did not exit cleanly:\n{}",
        suite.log()
    );
    let log = suite.log();
    assert!(!log.contains("panicked"), "{log}");
}

#[test]
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn single_node_with_name_namespace_and_remap() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST_SINGLE) {
        return;
    }
    let mut t = TestNode::new("cd_single_test");
    let js = t
        .node
        .publisher::<JointState>(
            "/robot1/measured_joints",
            &constraint_dynamics_nodes::ros::context::qos::reliable(10),
        )
        .unwrap();
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_forces"),
        &[
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-r",
            "__node:=wheel_forces",
            "-r",
            "__ns:=/robot1",
            "-r",
            // Relative FROM, as rcl expands it: the default joint_states in /robot1.
            "joint_states:=measured_joints",
            "-p",
            "state.odom_topic:=''",
        ],
        "single",
    );
    let forces = t.client::<GetConstraintForces>("/robot1/wheel_forces/get_constraint_forces");
    // The remapped joint states reach the node: the elbow's measured effort changes q̈.
    let req = GetConstraintForcesRequest {
        use_latest_state: true,
        ..Default::default()
    };
    let before = call(&forces, req.clone());
    assert!(before.success, "{}", before.message);
    let elbow = before
        .forces
        .v_names
        .iter()
        .position(|n| n == "arm_elbow")
        .unwrap();
    let deadline = std::time::Instant::now() + WAIT;
    loop {
        js.publish(JointState {
            name: vec!["arm_elbow".into()],
            effort: vec![3.0],
            ..Default::default()
        })
        .unwrap();
        let r = call(&forces, req.clone());
        if (r.qdd[elbow] - before.qdd[elbow]).abs() > 1e-3 {
            println!(
                "{TEST_SINGLE}: /robot1/wheel_forces serves; remapped joint states applied \
                 (elbow q̈ {:.4} → {:.4})",
                before.qdd[elbow], r.qdd[elbow]
            );
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "remapped joint states never applied"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(suite.stop(), "{}", suite.log());
}
