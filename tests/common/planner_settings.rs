//! Rollout settings for sampling planners on the differential drive (one copy for the rollout
//! tests and bench), and the reference they are held to.
// Each includer uses part of it.
#![allow(dead_code)]

use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Hold;
use constraint_dynamics::predict::{DriftControl, Method, Predictor};

/// `jacobian_spans` of the planner's settings: more than a rollout's pieces (168 steps, plus
/// one where a saturation exit cuts a step: ≈ 260).
pub const JACOBIAN_SPANS: usize = 1000;

/// The planner's settings: continuous wheel controllers (with their anti-windup) and ROS2 at a
/// third of the 50 ms command step, one F per rollout (`jacobian_spans` beyond a rollout's
/// steps; re-formed where a wheel saturates or comes back, and for each command's target),
/// projection, no error-estimate companion (2× the work). The diff drive's F depends on no
/// coordinate (a planar base on flat ground, round wheels) and on the velocities only
/// through small Coriolis and damping terms.
pub fn planner(scene: &Scene) -> Predictor {
    let mut scene = scene.clone();
    scene.file.actuators.hold = Hold::Continuous;
    Predictor::from_scene(&scene)
        .expect("predictor")
        .with_settings(|s| {
            s.method = Method::Ros2;
            s.dt = 0.05 / 3.0;
            s.jacobian_spans = JACOBIAN_SPANS;
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
