//! The suite's predictor topics end to end on the bundled mobile manipulator
//! (`params/default.yaml`): the `constraint_dynamics_suite` binary runs as a child process in
//! this test's loopback-only network namespace; the test feeds it a robot state
//! (`/joint_states`, `/odom`) and the command (0.3, 0.4) on `/cmd_vel`, reads
//! `predicted_odom`, `predicted_path` and `constraint_forces` with ros2-client and compares each
//! number with the core library's prediction from the same state (computed here). Also: the
//! parameter services (list/get, a refused and an accepted set) and the slip warning (flag in
//! the message + `/rosout`). The services: `suite_services.rs`.

use crate::common;
use crate::suite_fixture;

use common::*;
use constraint_dynamics::predict::PredictionRequest;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::ConstraintForces;
use constraint_dynamics_nodes::msg::nav_msgs::{Odometry, Path};
use constraint_dynamics_nodes::msg::rcl_interfaces::{
    GetParameters, ListParameters, SetParameters,
};
use ros2_client::ParameterValue;
use ros2_client::rcl_interfaces::{GetParametersRequest, ListParametersRequest};
use suite_fixture::*;

const TEST: &str = "suite_topics_match_the_core_library";

#[test]
#[ignore = "needs root (a loopback-only network namespace): run by tools/test.sh"]
fn suite_topics_match_the_core_library() {
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
    let odom_sub = t.subscribe::<Odometry>("/cd_predictor/predicted_odom");
    let path_sub = t.subscribe::<Path>("/cd_predictor/predicted_path");
    let forces_sub = t.subscribe::<ConstraintForces>("/cd_predictor/constraint_forces");
    let suite = spawn_suite("topics");
    let cmd = CMD;
    let (ql, vl) = core.projected(&state.q, &state.v);

    // ---- topics of the predictor (command (0.3, 0.4) on /cmd_vel) -----------------------------
    let expected_cmd = core.command([cmd.0, cmd.1], &ql);
    let commands = [(0.0, expected_cmd.clone())];
    let req = PredictionRequest::new(&ql, &vl)
        .commands(&commands)
        .horizon(1.0);
    let traj = core.predictor.predict(&req).unwrap();
    let last = traj.samples.last().unwrap().clone();
    let odom = take_until(&odom_sub, WAIT, |m: &Odometry| {
        close("predicted pose", &pose_of(&m.pose.pose), &last.q[..3], TOL)?;
        let t = &m.twist.twist;
        close(
            "predicted twist",
            &[t.linear.x, t.linear.y, t.angular.z],
            &last.v[..3],
            TOL,
        )
    })
    .unwrap_or_else(|e| panic!("predicted_odom never matched the core: {e}"));
    assert_eq!(
        (odom.header.frame_id.as_str(), odom.child_frame_id.as_str()),
        ("odom", "base_footprint")
    );
    let err = last.position_error_estimate();
    let sp = err.hypot(1e-3);
    for i in 0..6 {
        assert!(odom.pose.covariance[i * 7] > 0.0, "covariance[{i}] is zero");
        assert!(odom.twist.covariance[i * 7] > 0.0);
    }
    assert_close(
        "pose covariance x",
        &[odom.pose.covariance[0]],
        &[sp * sp],
        1e-9,
    );
    println!(
        "{TEST}: predicted_odom = core at the horizon: ({:.6}, {:.6}, {:.6}), σ = {sp:.3e} m \
         (error estimate {:.3e})",
        last.q[0],
        last.q[1],
        last.q[2],
        last.error_estimate.unwrap_or(0.0)
    );

    take_until(&path_sub, WAIT, |m: &Path| {
        if m.poses.len() != traj.samples.len() {
            return Err(format!("{} poses vs {}", m.poses.len(), traj.samples.len()));
        }
        for (k, (p, s)) in m.poses.iter().zip(&traj.samples).enumerate() {
            close(&format!("path pose {k}"), &pose_of(&p.pose), &s.q[..3], TOL)?;
        }
        Ok(())
    })
    .unwrap_or_else(|e| panic!("predicted_path never matched the core: {e}"));
    println!(
        "{TEST}: predicted_path = core ({} poses)",
        traj.samples.len()
    );

    // Forces at the start state under the controllers' torques there: the first control
    // tick's for held controllers, the continuous law's at t = 0 otherwise.
    let mut act = core.actuators.clone();
    act.reset();
    let mut tau = vec![0.0; scene.model.nv];
    if act.is_continuous() {
        act.start_continuous(&ql);
        act.begin_segment(&expected_cmd, 0.0);
        act.continuous_torque(0.0, &ql, &vl, &mut tau);
    } else {
        let dt = act
            .control_period
            .min(core.predictor.config().settings().sample_period)
            .min(1.0);
        act.update(&expected_cmd, &ql, &vl, dt, &mut tau);
    }
    let (_, f, gf) = core.forces(&ql, &vl, &tau);
    let m = take_until(&forces_sub, WAIT, |m: &ConstraintForces| {
        check_forces(&mut core, &ql, m, &f, &gf, TOL)
    })
    .unwrap_or_else(|e| panic!("constraint_forces never matched the core: {e}"));
    assert!(
        m.constraints.iter().all(|c| !c.slipping),
        "slip at μ = 0.8: {m:?}"
    );
    println!("{TEST}: constraint_forces topic = core (the controllers' torques at the start)");

    // ---- parameters ---------------------------------------------------------------------------
    let list = t.client::<ListParameters>("/cd_predictor/list_parameters");
    let names = call(
        &list,
        ListParametersRequest {
            prefixes: vec![],
            depth: 0,
        },
    )
    .result
    .names;
    for n in [
        "rate",
        "horizon",
        "model.scene_file",
        "slip.friction_coefficient",
        "use_sim_time",
    ] {
        assert!(names.iter().any(|x| x == n), "{n} not listed: {names:?}");
    }
    let get = t.client::<GetParameters>("/cd_predictor/get_parameters");
    let values = call(
        &get,
        GetParametersRequest {
            names: vec!["rate".into(), "slip.friction_coefficient".into()],
        },
    )
    .values;
    let values: Vec<ParameterValue> = values.into_iter().map(ParameterValue::from).collect();
    assert_eq!(
        values,
        vec![ParameterValue::Double(10.0), ParameterValue::Double(0.8)]
    );
    let set = t.client::<SetParameters>("/cd_predictor/set_parameters");
    let (ok, reason) = set_param(&set, "rate", ParameterValue::Double(50.0));
    assert!(!ok);
    assert!(reason.contains("cannot change"), "{}", reason);
    let (ok, reason) = set_param(
        &set,
        "slip.friction_coefficient",
        ParameterValue::Double(-1.0),
    );
    assert!(!ok && reason.contains("friction_coefficient"));
    println!(
        "{TEST}: parameters: {} listed; set rate refused (cannot change while the node runs); \
         μ = -1 refused ({})",
        names.len(),
        reason
    );

    // ---- slip: μ → 1e-4 makes the turning contacts slip: flag + /rosout warning ----------------
    let (ok, reason) = set_param(
        &set,
        "slip.friction_coefficient",
        ParameterValue::Double(1e-4),
    );
    assert!(ok, "{}", reason);
    take_until(&forces_sub, WAIT, |m: &ConstraintForces| {
        if m.constraints.iter().all(|c| c.slipping) {
            Ok(())
        } else {
            Err("not slipping yet".into())
        }
    })
    .unwrap_or_else(|e| panic!("no slip flag after μ = 1e-4: {e}"));
    let log = take_until(t.rosout(), WAIT, |l: &ros2_client::Log| {
        if l.name == "cd_predictor"
            && l.level == ros2_client::Log::WARN
            && l.msg.contains("slip")
            && l.msg.contains("0.0001")
        {
            Ok(())
        } else {
            Err(format!("{}: {}", l.name, l.msg))
        }
    })
    .unwrap_or_else(|e| panic!("no slip warning on /rosout: {e}"));
    println!(
        "{TEST}: slip flagged and logged to /rosout: \"{}\"",
        log.msg
    );

    stop_suite(suite);
}
