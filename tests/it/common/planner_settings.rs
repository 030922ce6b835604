//! Rollout settings for sampling planners on the differential drive (one copy for the rollout
//! tests and bench), and the reference they are held to.
// Each includer uses part of it.
#![allow(dead_code)]

use constraint_dynamics::Scene;
use constraint_dynamics::predict::{DriftControl, Method, Predictor};

/// The planner's settings: the scene's `rollouts:` (params/suite_diff_drive.yaml: continuous
/// wheel controllers with their anti-windup, ROS2 at a third of the 50 ms command step, one F
/// per rollout, projection, no error-estimate companion).
pub fn planner(scene: &Scene) -> Predictor {
    assert!(
        scene.file.rollouts.is_some(),
        "the scene declares no rollouts"
    );
    Predictor::from_scene(&scene.rollout_scene()).expect("predictor")
}

/// The wheel controllers as the scene declares them, held for `period` [s], integrated by RK4
/// at that period with projection.
pub fn held(scene: &Scene, period: f64) -> Predictor {
    let mut scene = scene.clone();
    scene.file.actuators.control_period = Some(period);
    Predictor::from_scene(&scene)
        .expect("predictor")
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.dt = period;
            s.drift = DriftControl::Projection;
            s.error_estimate = false;
        })
        .expect("settings")
}
