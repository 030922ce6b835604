//! The planner's rollout settings (continuous wheel controllers with anti-windup, ROS2 at
//! 16.7 ms on one F per rollout, `common/planner_settings.rs`) against the scene's own
//! controllers — held for the scene's 1 ms control period and integrated by RK4 at 1 ms — on
//! the bench's random command sequences: every rollout's final base pose within 1 cm and
//! 0.01 rad.

use crate::command_sequences;
use crate::planner_settings;

use command_sequences::sequences;
use constraint_dynamics::Scene;
use constraint_dynamics::predict::{PredictionRequest, RolloutOptions, Trajectory};
use std::path::PathBuf;

/// Worst distance [m] and yaw difference [rad] between the final base poses (x, y, yaw) of two
/// batches, with the index of each worst rollout.
fn worst(a: &[Trajectory], b: &[Trajectory]) -> ((f64, usize), (f64, usize)) {
    let mut out = ((0.0f64, 0), (0.0f64, 0));
    for (k, (a, b)) in a.iter().zip(b).enumerate() {
        let (qa, qb) = (&a.samples.last().unwrap().q, &b.samples.last().unwrap().q);
        let d = (qa[0] - qb[0]).hypot(qa[1] - qb[1]);
        let yaw = (qa[2] - qb[2]).abs();
        if d > out.0.0 {
            out.0 = (d, k);
        }
        if yaw > out.1.0 {
            out.1 = (yaw, k);
        }
    }
    out
}

#[test]
fn planner_rollouts_stay_within_1_cm_and_0_01_rad_of_the_scenes_controllers() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(root.join("params/suite_diff_drive.yaml")).unwrap();
    assert_eq!(scene.file.actuators.control_period, Some(0.001));
    let (n, steps) = (100, 56);
    let seqs = sequences(n, steps);
    let start = PredictionRequest::new(&scene.q0, &scene.v0);
    let opts = RolloutOptions {
        step: 0.05,
        threads: 0,
    };
    let reference = planner_settings::held(&scene, 0.001)
        .rollouts(&start, &seqs, opts)
        .unwrap();
    let fast = planner_settings::planner(&scene)
        .rollouts(&start, &seqs, opts)
        .unwrap();
    // The wheels do saturate: the anti-windup is exercised (5 N·m, urdf/diff_drive.urdf).
    let saturated = reference
        .iter()
        .filter(|t| {
            (t.samples.iter()).any(|s| s.actuator_torque.iter().any(|x| x.abs() >= 5.0 - 1e-9))
        })
        .count();
    assert!(saturated > n / 2, "{saturated} of {n} rollouts saturate");
    let ((d, kd), (yaw, ky)) = worst(&fast, &reference);
    let (evaluations, jacobians) = fast
        .iter()
        .fold((0, 0), |(e, j), t| (e + t.evaluations, j + t.jacobians));
    println!(
        "planner settings vs the 1 ms held controllers over {n} × {steps} × 50 ms: worst \
         {d:.2e} m (rollout {kd}), {yaw:.2e} rad (rollout {ky}); per rollout {} evaluations, {} \
         Jacobians; {saturated} rollouts saturate",
        evaluations / n,
        jacobians / n,
    );
    // For the record: the bench's former settings (controllers held for 5 ms) from the same.
    let held5 = planner_settings::held(&scene, 0.005)
        .rollouts(&start, &seqs, opts)
        .unwrap();
    let ((d5, _), (yaw5, _)) = worst(&held5, &reference);
    println!("controllers held for 5 ms vs 1 ms: worst {d5:.2e} m, {yaw5:.2e} rad");
    // One F per rollout, re-formed at each saturation change and command.
    assert!(fast.iter().all(|t| t.jacobians == 1));
    assert!(d <= 3e-3, "{d} m");
    assert!(yaw <= 1e-2, "{yaw} rad");
}

#[test]
fn a_jacobian_every_zero_spans_is_refused_by_name() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(root.join("params/suite_diff_drive.yaml")).unwrap();
    let e = constraint_dynamics::predict::Predictor::from_scene(&scene)
        .unwrap()
        .with_settings(|s| s.jacobian_spans = 0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("integration.jacobian_spans = 0"), "{e}");
}
