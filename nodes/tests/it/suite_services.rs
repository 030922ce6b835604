//! The suite's services end to end on the bundled mobile manipulator (`params/default.yaml`):
//! the `constraint_dynamics_suite` binary runs as a child process in this test's loopback-only
//! network namespace; the test feeds it a robot state (`/joint_states`, `/odom`) and a command
//! (`/cmd_vel`), calls `~/get_constraint_forces` (latest state, a state in the request,
//! positional and by name), `~/project_velocity`, `~/predict` and `~/rollouts` with ros2-client,
//! and compares each number with the core library's for the same state (computed here). Last, a
//! heavier chassis on `/robot_description`: the forces follow the new model. The predictor's
//! topics and parameters: `suite_topics.rs`.

use crate::common;
use crate::suite_fixture;

use std::collections::BTreeMap;
use std::time::Duration;

use common::*;
use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use constraint_dynamics::projection::{
    PerCoordinate, ProjectionRequest, Status, VelocityProjector, project_system,
};
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesRequest, Predict, PredictRequest, ProjectVelocity,
    ProjectVelocityRequest, Rollouts, RolloutsRequest,
};
use constraint_dynamics_nodes::msg::std_msgs::StringMsg;
use suite_fixture::*;

const TEST: &str = "suite_services_match_the_core_library";

#[test]
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn suite_services_match_the_core_library() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST) {
        return;
    }
    let mut t = TestNode::new("cd_test");
    let Fixture {
        scene,
        mut core,
        state,
        feed: _feed,
    } = Fixture::new(&mut t);
    let suite = spawn_suite("services");

    // ---- ~/get_constraint_forces at the latest state (waits until the feed is applied) ----
    let forces = t.client::<GetConstraintForces>("/cd_forces/get_constraint_forces");
    let (ql, vl) = core.projected(&state.q, &state.v);
    let (qdd, f, gf) = core.forces(&ql, &vl, &state.effort);
    let latest = GetConstraintForcesRequest {
        use_latest_state: true,
        ..Default::default()
    };
    let deadline = std::time::Instant::now() + WAIT;
    loop {
        let r = call(&forces, latest.clone());
        assert!(r.success, "{}", r.message);
        let check = close("qdd", &r.qdd, &qdd, TOL)
            .and_then(|_| check_forces(&mut core, &ql, &r.forces, &f, &gf, TOL));
        match check {
            Ok(()) => break,
            Err(e) if std::time::Instant::now() > deadline => {
                panic!("latest-state forces never matched the core: {e}")
            }
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    println!("{TEST}: get_constraint_forces (latest state, measured efforts) = core");

    // ---- ~/get_constraint_forces at a state in the request --------------------------------
    let mut q2 = state.q.clone();
    q2[2] = -1.1;
    let mut v2 = state.v.clone();
    v2[5] = 0.7;
    let tau2: Vec<f64> = (0..scene.model.nv).map(|i| 0.1 * i as f64 - 0.3).collect();
    let r = call(
        &forces,
        GetConstraintForcesRequest {
            use_latest_state: false,
            q: q2.clone(),
            v: v2.clone(),
            tau: tau2.clone(),
            ..Default::default()
        },
    );
    assert!(r.success, "{}", r.message);
    let (qdd, f, gf) = core.forces(&q2, &v2, &tau2);
    assert_close("qdd (request state)", &r.qdd, &qdd, TOL);
    check_forces(&mut core, &q2, &r.forces, &f, &gf, TOL).unwrap();
    // By name: only the elbow changes, the rest is the latest state.
    let r = call(
        &forces,
        GetConstraintForcesRequest {
            q_names: vec!["arm_elbow".into()],
            q: vec![1.4],
            v_names: vec!["arm_elbow".into()],
            v: vec![-0.3],
            ..Default::default()
        },
    );
    assert!(r.success, "{}", r.message);
    let (mut q3, mut v3) = (state.q.clone(), state.v.clone());
    q3[scene.model.q_index("arm_elbow").unwrap()] = 1.4;
    v3[scene.model.v_index("arm_elbow").unwrap()] = -0.3;
    let (qdd, f, gf) = core.forces(&q3, &v3, &vec![0.0; scene.model.nv]);
    assert_close("qdd (named state)", &r.qdd, &qdd, TOL);
    check_forces(&mut core, &q3, &r.forces, &f, &gf, TOL).unwrap();
    println!("{TEST}: get_constraint_forces (state in the request, positional and by name) = core");

    // ---- ~/project_velocity -------------------------------------------------------------------
    let project = t.client::<ProjectVelocity>("/cd_projection/project_velocity");
    let mut req = ProjectVelocityRequest {
        use_latest_state: true,
        use_twist: true,
        joint_names: vec!["arm_elbow".into()],
        joint_velocities: vec![0.3],
        bound_names: vec!["right_wheel_joint".into()],
        lower: vec![f64::NEG_INFINITY],
        upper: vec![6.0],
        ..Default::default()
    };
    req.base_twist = twist(0.4, 0.5);
    req.base_twist.linear.y = 0.1;
    let r = call(&project, req);
    let mut pr = ProjectionRequest {
        base_twist: Some(vec![0.4, 0.1, 0.5]),
        lower: Some(PerCoordinate::Named(BTreeMap::from([(
            "right_wheel_joint".to_string(),
            None,
        )]))),
        upper: Some(PerCoordinate::Named(BTreeMap::from([(
            "right_wheel_joint".to_string(),
            Some(6.0),
        )]))),
        ..Default::default()
    };
    pr.joints.insert("arm_elbow".into(), 0.3);
    let mut projector = VelocityProjector::new(core.sys.model(), core.sys.constraints());
    let expected = project_system(&mut projector, &mut core.sys, &ql, &vl, &pr).unwrap();
    assert_eq!(expected.status, Status::Optimal);
    assert!(
        r.success && r.status == "optimal",
        "{} {}",
        r.status,
        r.message
    );
    let ev = expected.v.clone().unwrap();
    assert_close("projected v", &r.v, &ev, TOL);
    assert_close(
        "impulses",
        &r.impulses,
        &expected.impulses.clone().unwrap(),
        1e-7,
    );
    assert_close(
        "base twist",
        &[
            r.base_twist.linear.x,
            r.base_twist.linear.y,
            r.base_twist.angular.z,
        ],
        &ev[..3],
        TOL,
    );
    assert_eq!(r.v_names, scene.model.v_names);
    let expected_bounds: Vec<String> = expected
        .active_bounds
        .iter()
        .map(|b| {
            let side = match b.side {
                constraint_dynamics::projection::Side::Lower => ">=",
                constraint_dynamics::projection::Side::Upper => "<=",
            };
            format!("{} {side} {} ({})", b.coordinate, b.value, b.source.label())
        })
        .collect();
    assert_eq!(r.active_bounds, expected_bounds);
    println!(
        "{TEST}: project_velocity = core ({}; active {:?})",
        r.message, r.active_bounds
    );

    // ---- ~/predict ----------------------------------------------------------------------------
    let predict = t.client::<Predict>("/cd_prediction/predict");
    let commands = [(0.4, 0.3), (0.2, -0.5)];
    let r = call(
        &predict,
        PredictRequest {
            use_latest_state: false,
            q: state.q.clone(),
            v: state.v.clone(),
            commands: commands.iter().map(|&(v, w)| twist(v, w)).collect(),
            command_period: 0.5,
            horizon: 1.0,
            with_forces: true,
            ..Default::default()
        },
    );
    assert!(r.success, "{}", r.message);
    let cmds: Vec<(f64, Command)> = commands
        .iter()
        .enumerate()
        .map(|(k, &(v, w))| (0.5 * k as f64, core.command([v, w], &state.q)))
        .collect();
    let req = PredictionRequest::new(&state.q, &state.v)
        .commands(&cmds)
        .horizon(1.0)
        .forces(true);
    let traj = core.predictor.predict(&req).unwrap();
    let times: Vec<f64> = traj.samples.iter().map(|s| s.t).collect();
    assert_close("predict times", &r.times, &times, TOL);
    assert_eq!(r.path.poses.len(), traj.samples.len());
    assert_eq!(r.forces.len(), traj.samples.len());
    for (k, (p, s)) in r.path.poses.iter().zip(&traj.samples).enumerate() {
        assert_close(
            &format!("predict pose {k}"),
            &pose_of(&p.pose),
            &s.q[..3],
            TOL,
        );
        let lam: Vec<f64> = r.forces[k]
            .constraints
            .iter()
            .flat_map(|c| c.multipliers.clone())
            .collect();
        assert_close(
            &format!("predict lambda {k}"),
            &lam,
            s.lambda.as_ref().unwrap(),
            1e-8,
        );
    }
    let last = traj.samples.last().unwrap();
    // The estimate of each kind in its unit (~1e-5 … 1e-4 here): the core's to 1e-6 of each.
    let by_kind = last.error_estimate_by_kind.unwrap();
    for (what, node, core) in [
        (
            "position_error_estimate",
            r.position_error_estimate,
            last.position_error_estimate(),
        ),
        (
            "orientation_error_estimate",
            r.orientation_error_estimate,
            last.orientation_error_estimate(),
        ),
        (
            "joint_error_estimate_rad",
            r.joint_error_estimate_rad,
            by_kind.joint_rad,
        ),
        (
            "joint_error_estimate_m",
            r.joint_error_estimate_m,
            by_kind.joint_m,
        ),
    ] {
        assert!(
            (node - core).abs() <= 1e-6 * core,
            "{what}: node {node:e}, core {core:e}"
        );
    }
    assert_eq!(r.path.header.frame_id, "odom");
    println!(
        "{TEST}: predict ({} samples) = core; {}",
        r.times.len(),
        r.message
    );

    // ---- ~/rollouts: each rollout is the core's single prediction of that sequence -----------
    let rollouts = t.client::<Rollouts>("/cd_prediction/rollouts");
    let sequences = [
        [(0.4, 0.3), (0.2, -0.5)],
        [(0.0, 0.0), (-0.3, 0.8)],
        [(0.5, 0.0), (0.5, 0.0)],
    ];
    let (len, step) = (2, 0.25);
    let r = call(
        &rollouts,
        RolloutsRequest {
            use_latest_state: false,
            q: state.q.clone(),
            v: state.v.clone(),
            commands: sequences
                .iter()
                .flatten()
                .map(|&(v, w)| twist(v, w))
                .collect(),
            sequence_length: len as u32,
            step,
            with_forces: true,
        },
    );
    assert!(r.success, "{}", r.message);
    assert_eq!(r.header.frame_id, "odom");
    assert_eq!((r.poses.len(), r.twists.len(), r.forces.len()), (6, 6, 6));
    for (j, seq) in sequences.iter().enumerate() {
        let cmds: Vec<(f64, Command)> = seq
            .iter()
            .enumerate()
            .map(|(k, &(v, w))| (step * k as f64, core.command([v, w], &state.q)))
            .collect();
        let mut single = Predictor::from_scene(&scene.rollout_scene())
            .unwrap()
            .with_settings(|s| {
                s.sample_period = step;
                s.error_estimate = false;
            })
            .unwrap();
        let req = PredictionRequest::new(&state.q, &state.v)
            .commands(&cmds)
            .horizon(len as f64 * step)
            .forces(true);
        let traj = single.predict(&req).unwrap();
        assert_eq!(traj.samples.len(), len + 1);
        for (k, s) in traj.samples[1..].iter().enumerate() {
            let i = j * len + k;
            let what = format!("rollout {j} step {k}");
            assert_close(&what, &pose_of(&r.poses[i]), &s.q[..3], TOL);
            let tw = &r.twists[i];
            let expected = scene.model.base_twist(&s.v);
            assert_close(
                &what,
                &[tw.linear.x, tw.linear.y, tw.angular.z],
                &[expected.linear[0], expected.linear[1], expected.angular[2]],
                TOL,
            );
            let lam: Vec<f64> = r.forces[i]
                .constraints
                .iter()
                .flat_map(|c| c.multipliers.clone())
                .collect();
            assert_close(&what, &lam, s.lambda.as_ref().unwrap(), 1e-8);
        }
    }
    println!(
        "{TEST}: rollouts (3 × 2 steps) = core single predictions; {}",
        r.message
    );

    // ---- /robot_description: a heavier chassis re-plans with the new model ---------------------
    let urdf = std::fs::read_to_string(repo_root().join("urdf/mobile_manipulator.urdf")).unwrap();
    let heavy = urdf.replacen("<mass value=\"8.0\"/>", "<mass value=\"16.0\"/>", 1);
    assert_ne!(heavy, urdf, "chassis mass not found in the URDF");
    let description = description_publisher(&mut t);
    description
        .publish(StringMsg {
            data: heavy.clone(),
        })
        .unwrap();
    let heavy_scene = Scene::from_parts(&scene.path, scene.file.clone(), &heavy, "heavy").unwrap();
    let mut heavy_core = Core::new(&heavy_scene);
    let (qh, vh) = heavy_core.projected(&state.q, &state.v);
    let (qdd_heavy, _, _) = heavy_core.forces(&qh, &vh, &state.effort);
    let deadline = std::time::Instant::now() + WAIT;
    loop {
        let r = call(&forces, latest.clone());
        if close("qdd (heavy)", &r.qdd, &qdd_heavy, TOL).is_ok() {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the forces node did not switch to the new URDF: qdd {:?} vs {:?}",
            r.qdd,
            qdd_heavy
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    println!("{TEST}: /robot_description: model rebuilt, forces = core on the new URDF");

    stop_suite(suite);
}
