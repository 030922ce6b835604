//! A payload set at run time, through `~/set_payload` by a real ROS 2 peer (rclpy with
//! rmw_fastrtps_cpp, `nodes/tests/peers/payload_peer.py`) and through the `payload.*`
//! parameters, changes what the forces node computes as the closed form says and as the core
//! computes it with the same payload in the scene.
//!
//! The scene is the floating cart of tests/data/cart_tall_mass.yaml (32.5 kg) at rest on its
//! two wheels and caster. At rest with its height, roll and pitch held by the contacts, no
//! point of it accelerates vertically, so the contacts carry the whole weight: the constraint
//! force along the base's z axis (the generalized force of `root_joint:vz_local`, the base
//! level) is (m_robot + m_payload)·g.
//!
//! The same payload set on the predictor moves its `~/acceleration_limits` as the closed forms
//! of docs/projection.md say and as the CLI's `envelope` computes them for the same payload in
//! the scene (tests/data/cart_tall_mass_payload.yaml).
//!
//! Needs root (a loopback-only network namespace) and the peer venv
//! (`tools/ros2/setup_peer_venv.sh`; `CD_ROS2_VENV`, default `<repo>/.venv-ros2`): `#[ignore]`d
//! in a plain `cargo test`, run by `tools/test.sh`; a missing prerequisite fails the test.

use crate::common;

use std::time::Duration;

use common::*;
use constraint_dynamics::applied::constraint_forces_at;
use constraint_dynamics::envelope::{EnvelopeData, EnvelopeModel, acceleration_envelope};
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::model::Payload;
use constraint_dynamics::{Scene, System};
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::{
    GetConstraintForces, GetConstraintForcesRequest, GetConstraintForcesResponse,
};
use constraint_dynamics_nodes::msg::rcl_interfaces::SetParameters;
use ros2_client::ParameterValue;
use serde_json::Value;

const TEST: &str = "a_payload_set_by_rclpy_changes_the_forces_as_the_core_computes_them";
const LIMITS_TEST: &str =
    "a_payload_set_by_rclpy_changes_the_acceleration_limits_as_the_cli_computes_them";

const G: f64 = 9.81;
/// The cart's mass [kg] (urdf/cart_tall_mass.urdf: 20 + 2 × 1 + 0.5 + 10).
const M_ROBOT: f64 = 32.5;
/// The weight's share of rounding in the constraint solve (a 7-row KKT system of O(10) entries):
/// measured 0 to 1.7e-16 relative.
const WEIGHT_TOL: f64 = 1e-14;

/// The forces at the scene's initial state, at rest, without torques.
fn forces_at_rest(
    client: &ros2_client::Client<GetConstraintForcesRequest, GetConstraintForcesResponse>,
) -> GetConstraintForcesResponse {
    let mut q = vec![0.0; 9];
    q[6] = 1.0; // root_joint:qw
    let r = call(
        client,
        GetConstraintForcesRequest {
            use_latest_state: false,
            q,
            v: vec![0.0; 8],
            ..Default::default()
        },
    );
    assert!(r.success, "{}", r.message);
    r
}

/// The constraint force along the base's z axis [N].
fn vertical_force(r: &GetConstraintForcesResponse) -> f64 {
    let i = r
        .forces
        .v_names
        .iter()
        .position(|n| n == "root_joint:vz_local")
        .expect("a floating base");
    r.forces.generalized_force[i]
}

fn assert_weight(what: &str, r: &GetConstraintForcesResponse, mass: f64) {
    let (got, expect) = (vertical_force(r), mass * G);
    let rel = (got - expect).abs() / expect;
    println!("{TEST}: achieved {what}: {got} N vs {mass} kg × g = {expect} N (rel {rel:.1e})");
    assert!(rel < WEIGHT_TOL, "{what}: {got} vs {expect}");
}

#[test]
#[ignore = "needs root and the peer venv: run by tools/test.sh"]
fn a_payload_set_by_rclpy_changes_the_forces_as_the_core_computes_them() {
    let _group = crate::common::exclusive_group(module_path!());
    let python = peer_python(TEST);
    if !in_namespace_or_reexec(TEST) {
        return; // the run inside the namespace passed
    }
    let mut t = TestNode::new("cd_payload_test");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--node",
            "forces",
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            "model.scene_file:=tests/data/cart_tall_mass.yaml",
        ],
        "payload",
    );
    let forces = t.client::<GetConstraintForces>("/cd_forces/get_constraint_forces");
    assert_weight("weight without payload", &forces_at_rest(&forces), M_ROBOT);

    // rclpy sets 2 kg on tall_mass (after two bad requests the node must refuse and survive).
    let good = serde_json::json!({
        "frame": "tall_mass",
        "inertia": {"m": 2.0, "com": {"x": 0.3, "y": 0.1, "z": 0.5},
                    "ixx": 0.01, "ixy": 0.001, "ixz": 0.0, "iyy": 0.012, "iyz": 0.0, "izz": 0.008},
    });
    let out = run_peer(&python, &good);
    assert_eq!(out["ok"], true, "payload_peer.py: {out}\n{}", suite.log());
    assert_eq!(out["negative_mass"]["success"], false, "{out}");
    let m = out["negative_mass"]["message"].as_str().unwrap();
    assert!(m.starts_with("inertia.m"), "{m}");
    assert_eq!(out["unknown_frame"]["success"], false, "{out}");
    let m = out["unknown_frame"]["message"].as_str().unwrap();
    assert!(m.contains("frame: unknown frame 'gripper'"), "{m}");
    assert_eq!(out["good"]["success"], true, "{out}");
    assert_eq!(out["diagnostics_payload"], "2.0 kg on tall_mass");

    let with_service = forces_at_rest(&forces);
    assert_weight(
        "weight with 2 kg by ~/set_payload",
        &with_service,
        M_ROBOT + 2.0,
    );
    // As the core computes it with the same payload in the scene: the same arithmetic on the
    // same model, so the same numbers.
    let payload = Payload {
        frame: "tall_mass".into(),
        mass: 2.0,
        com: [0.3, 0.1, 0.5],
        inertia: [0.01, 0.001, 0.0, 0.012, 0.0, 0.008],
    };
    let scene = Scene::load(repo_root().join("tests/data/cart_tall_mass.yaml"))
        .unwrap()
        .with_payload(&payload)
        .unwrap();
    let mut sys = System::from_scene(&scene).unwrap();
    let mut elements = ForceElements::new(sys.model(), &scene.file.forces).unwrap();
    let core = constraint_forces_at(
        &mut sys,
        &mut elements,
        (0.0, &scene.q0, &scene.v0),
        &[0.0; 8],
    )
    .unwrap();
    assert_close("q̈ node vs core", &with_service.qdd, &core.qdd, 1e-15);
    assert_close(
        "Jᵀλ node vs core",
        &with_service.forces.generalized_force,
        &core.generalized_force,
        1e-15,
    );

    // A parameter set replaces the service's payload; a frame with mass 0 is none.
    let set = t.client::<SetParameters>("/cd_forces/set_parameters");
    let ok = |(accepted, reason): (bool, String)| assert!(accepted, "{reason}");
    let (accepted, reason) = set_param(
        &set,
        "payload.frame",
        ParameterValue::String("nowhere".into()),
    );
    assert!(!accepted && reason.contains("payload.frame"), "{reason}");
    ok(set_param(
        &set,
        "payload.frame",
        ParameterValue::String("base_link".into()),
    ));
    assert_weight(
        "weight with payload.frame set, mass 0",
        &forces_at_rest(&forces),
        M_ROBOT,
    );
    ok(set_param(&set, "payload.mass", ParameterValue::Double(5.0)));
    assert_weight(
        "weight with 5 kg by payload.*",
        &forces_at_rest(&forces),
        M_ROBOT + 5.0,
    );
    ok(set_param(&set, "payload.mass", ParameterValue::Double(0.0)));
    ok(set_param(
        &set,
        "payload.frame",
        ParameterValue::String(String::new()),
    ));
    assert_weight(
        "weight back to the scene's (none)",
        &forces_at_rest(&forces),
        M_ROBOT,
    );
    assert!(suite.stop(), "{}", suite.log());
}

fn run_peer(python: &std::path::Path, good: &Value) -> Value {
    peer_report(
        python,
        "payload_peer.py",
        &["/cd_forces".to_string(), good.to_string()],
        Duration::from_secs(120),
    )
}

/// The four limits of `scene` at its initial state (at rest), as the CLI's `envelope` computes
/// them (no force elements in the cart's scene).
fn core_limits(scene: &Scene) -> [f64; 4] {
    let mut sys = System::from_scene(scene).unwrap();
    let em = EnvelopeModel::from_scene(scene, &sys).unwrap();
    let mut ed = EnvelopeData::new(&em);
    let zero = vec![0.0; sys.model().nv];
    let e = acceleration_envelope(&mut sys, &em, &mut ed, &scene.q0, &scene.v0, &zero).unwrap();
    [
        e.forward_acceleration.max,
        e.forward_deceleration.max,
        e.yaw_acceleration_left.max,
        e.yaw_acceleration_right.max,
    ]
}

#[test]
#[ignore = "needs root and the peer venv: run by tools/test.sh"]
fn a_payload_set_by_rclpy_changes_the_acceleration_limits_as_the_cli_computes_them() {
    let _group = crate::common::exclusive_group(module_path!());
    let python = peer_python(LIMITS_TEST);
    if !in_namespace_or_reexec(LIMITS_TEST) {
        return; // the run inside the namespace passed
    }
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--node",
            "predictor",
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            "model.scene_file:=tests/data/cart_tall_mass.yaml",
            "-p",
            "covariance.propagate:=false",
        ],
        "payload_limits",
    );
    // The payload of tests/data/cart_tall_mass_payload.yaml: 5 kg 0.9 m above base_link, 0.1 m
    // behind the axle.
    let good = serde_json::json!({
        "frame": "base_link",
        "inertia": {"m": 5.0, "com": {"x": -0.1, "y": 0.0, "z": 0.9},
                    "ixx": 0.1, "ixy": 0.0, "ixz": 0.0, "iyy": 0.08, "iyz": 0.0, "izz": 0.05},
    });
    let out = peer_report(
        &python,
        "payload_limits_peer.py",
        &[good.to_string()],
        Duration::from_secs(90),
    );
    assert_eq!(
        out["ok"],
        true,
        "payload_limits_peer.py: {out}\n{}",
        suite.log()
    );
    assert_eq!(out["set_payload"]["success"], true, "{out}");
    // Closed forms (docs/projection.md): the effort limit 2 τ_max / (r (M + 2 I_w / r²)) and the
    // caster's lift-off braking limit g |Σ m x| / (Σ m z + 2 I_w / r), with the payload's 5 kg
    // at x = −0.1 m, z = 1.0 m added to M = 32.5 kg, Σ m x = −2.7 kg·m, Σ m z = 13.225 kg·m.
    let closed = [
        ([8.0 / 3.35, G * 2.7 / 13.325], "before"),
        ([8.0 / 3.85, G * 3.2 / 18.325], "after"),
    ];
    let dir = repo_root().join("tests/data");
    let cli = [
        core_limits(&Scene::load(dir.join("cart_tall_mass.yaml")).unwrap()),
        core_limits(&Scene::load(dir.join("cart_tall_mass_payload.yaml")).unwrap()),
    ];
    for ((want, key), core) in closed.iter().zip(cli) {
        let msgs = out[key].as_array().unwrap();
        for m in msgs {
            let got: Vec<f64> = (0..4).map(|i| m[i][1].as_f64().unwrap()).collect();
            assert!(
                (0..4).all(|i| m[i][0] == 0),
                "{key}: every limit bounded: {m}"
            );
            for (i, w) in want.iter().enumerate() {
                let rel = (got[i] - w).abs() / w;
                assert!(rel < 1e-8, "{key} limit {i}: {} vs closed form {w}", got[i]);
            }
            assert_close(&format!("{key}: node vs CLI"), &got, &core, 1e-12);
        }
        println!(
            "{LIMITS_TEST}: achieved {key}: {} messages, forward {:.6} m/s² (closed form {:.6}), \
             braking {:.6} m/s² (closed form {:.6})",
            msgs.len(),
            core[0],
            want[0],
            core[1],
            want[1]
        );
    }
    assert!(suite.stop(), "{}", suite.log());
}
