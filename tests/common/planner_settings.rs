//! Rollout settings for sampling planners on the differential drive (one copy for the rollout
//! tests and bench), and the reference they are held to.
// Each includer uses part of it.
#![allow(dead_code)]

use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Hold;
use constraint_dynamics::predict::{DriftControl, Method, Predictor};

/// The planner's settings: continuous wheel controllers (with their anti-windup) and ROS2 at a
/// third of the 50 ms command step, `jacobian_spans: 2` (a fresh F at a command's first two
/// steps, and where a wheel saturates or comes back), projection, no error-estimate companion
/// (2× the work).
pub fn planner(scene: &Scene) -> Predictor {
    let mut scene = scene.clone();
    scene.file.actuators.hold = Hold::Continuous;
    Predictor::from_scene(&scene)
        .expect("predictor")
        .with_settings(|s| {
            s.method = Method::Ros2;
            s.dt = 0.05 / 3.0;
            s.jacobian_spans = 2;
            s.drift = DriftControl::Projection;
            s.error_estimate = false;
        })
        .expect("settings")
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
