//! Sample forces include the actuator torques. The differential drive of
//! `params/suite_diff_drive.yaml` starts at rest and is commanded (0.5 m/s, 0.4 rad/s): the
//! wheel targets (v ∓ b/2 ω)/r = 8.64 and 11.36 rad/s give PI outputs
//! kp e + ki e dt = 8.81 and 11.59 N·m, both above the URDF effort limit of 5 N·m, so each wheel
//! is driven with exactly 5 N·m over the first control period. The first sample's multipliers are
//! the constrained dynamics at rest with τ = (0, 0, 0, 5, 5).

use crate::common;
use common::*;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use constraint_dynamics::{Scene, System};

/// The first sample of a prediction from rest under (0.5 m/s, 0.4 rad/s), and λ of the
/// constrained dynamics at rest under the wheel torques `applied` [N·m] — what the controllers
/// give over the first control period.
fn first_sample_and_lambda_at(
    scene: &Scene,
    applied: f64,
) -> (constraint_dynamics::predict::Sample, Vec<f64>) {
    let mut p = Predictor::from_scene(scene).unwrap();
    let cmd = Command {
        base_twist: Some([0.5, 0.4]),
        ..Default::default()
    };
    let commands = [(0.0, cmd)];
    let req = PredictionRequest::new(&scene.q0, &scene.v0)
        .commands(&commands)
        .horizon(0.02)
        .forces(true);
    let first = p.predict(&req).unwrap().samples[0].clone();
    let mut sys = System::from_scene(scene).unwrap();
    let tau = [0.0, 0.0, 0.0, applied, applied];
    sys.forward_dynamics(&scene.q0, &scene.v0, &tau, true)
        .unwrap();
    (first, sys.multipliers().lambda.as_slice().to_vec())
}

#[test]
fn first_sample_forces_include_the_saturated_wheel_torques() {
    let scene = Scene::load(repo_dir().join("params/suite_diff_drive.yaml")).unwrap();
    let (first, lambda) = first_sample_and_lambda_at(&scene, 5.0);
    assert_close(
        "λ at t = 0 with the held wheel torques",
        first.lambda.as_deref().unwrap(),
        &lambda,
        // The predictor's first sample and a direct evaluation at the same state and torques
        // run the same arithmetic: achieved 0; floor 1e-15.
        1e-15,
    );
    // The wheels push the base forward: the longitudinal contact forces are positive.
    let f = first.forces.clone().unwrap();
    assert!(f.iter().all(|c| c.force[0] > 1.0), "{f:?}");
}

/// `traction_torque` clamps each wheel to the lesser of it and the URDF effort: 3 N·m under the
/// 5 N·m effort drives both wheels with exactly 3 N·m over the first period; 7 N·m leaves the
/// URDF's 5.
#[test]
fn traction_torque_clamps_the_wheels_below_the_urdf_effort() {
    let loaded = Scene::load(repo_dir().join("params/suite_diff_drive.yaml")).unwrap();
    for (traction, applied) in [(3.0, 3.0), (7.0, 5.0)] {
        let mut scene = loaded.clone();
        if let Some(d) = scene.file.actuators.diff_drive.as_mut() {
            d.traction_torque = Some(traction);
        }
        let (first, lambda) = first_sample_and_lambda_at(&scene, applied);
        assert_close(
            &format!("λ at t = 0, traction_torque {traction} N·m"),
            first.lambda.as_deref().unwrap(),
            &lambda,
            1e-15,
        );
    }
    let mut bad = loaded.clone();
    if let Some(d) = bad.file.actuators.diff_drive.as_mut() {
        d.traction_torque = Some(-1.0);
    }
    let e = Predictor::from_scene(&bad).err().unwrap().to_string();
    assert!(e.contains("traction_torque"), "{e}");
}

/// `traction_load_transfer: κ` takes κ |τ_c| off both wheels' clamp, τ_c their mean torque: both
/// pushing forward beyond it (8.81 and 11.59 N·m asked) share L = T − κ L, so T = 3 N·m and
/// κ = 0.5 drive each wheel with T/(1 + κ) = 2 N·m exactly. κ without a traction torque, or
/// negative, is refused naming the key.
#[test]
fn load_transfer_lowers_both_wheels_clamps_under_a_common_torque() {
    let loaded = Scene::load(repo_dir().join("params/suite_diff_drive.yaml")).unwrap();
    let mut scene = loaded.clone();
    if let Some(d) = scene.file.actuators.diff_drive.as_mut() {
        (d.traction_torque, d.traction_load_transfer) = (Some(3.0), Some(0.5));
    }
    let (first, lambda) = first_sample_and_lambda_at(&scene, 2.0);
    assert_close(
        "λ at t = 0, traction 3 N·m with load transfer 0.5",
        first.lambda.as_deref().unwrap(),
        &lambda,
        1e-15,
    );
    for (traction, kappa) in [(None, 0.5), (Some(3.0), -0.1), (Some(3.0), f64::NAN)] {
        let mut bad = loaded.clone();
        if let Some(d) = bad.file.actuators.diff_drive.as_mut() {
            (d.traction_torque, d.traction_load_transfer) = (traction, Some(kappa));
        }
        let e = Predictor::from_scene(&bad).err().unwrap().to_string();
        assert!(e.contains("traction_load_transfer"), "{e}");
    }
}
