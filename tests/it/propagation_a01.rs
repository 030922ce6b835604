//! IFToMM A01 high-precision bar: the simple pendulum (1 kg point mass, massless 1 m link, released
//! horizontal) over 2000 s against the closed form (Jacobi's sn, `common/closed_forms.rs`) at
//! every sample. The benchmark's bar is 1e-3 m; dopri5 at rtol 1e-11 reaches 3.94e-5 m, so the
//! test asserts 1e-4 m (2.5× the achieved error): a regression that loses most of the
//! accuracy fails here long before it would fail the benchmark's bar.

use crate::closed_forms;

use closed_forms::a01_position;
use constraint_dynamics::Scene;
use constraint_dynamics::predict::{Method, PredictionRequest, Predictor};
use std::path::PathBuf;
use std::time::Instant;

fn pendulum() -> (Predictor, Scene) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("params/pendulum_a01.yaml");
    let scene = Scene::load(path).unwrap();
    (Predictor::from_scene(&scene).unwrap(), scene)
}

/// Max over the samples of |P − P_ref| [m].
fn max_position_error(traj: &constraint_dynamics::predict::Trajectory) -> f64 {
    traj.samples
        .iter()
        .map(|s| {
            let (x, z) = a01_position(s.t, 1.0);
            ((s.q[0].cos() - x).powi(2) + (-s.q[0].sin() - z).powi(2)).sqrt()
        })
        .fold(0.0, f64::max)
}

#[test]
fn a01_pendulum_meets_the_high_precision_bar_over_2000_s() {
    let (p, scene) = pendulum();
    let mut p = p
        .with_settings(|s| {
            s.method = Method::Dopri5;
            s.rtol = 1e-11;
            s.atol = 1e-11;
            s.sample_period = 1.0;
        })
        .unwrap();
    let req = PredictionRequest::new(&scene.q0, &scene.v0).horizon(2000.0);
    let start = Instant::now();
    let traj = p.predict(&req).unwrap();
    let cpu = start.elapsed().as_secs_f64();
    let err = max_position_error(&traj);
    let last = traj.samples.last().unwrap();
    println!(
        "A01 dopri5 rtol 1e-11: max position error {err:.3e} m over 2000 s, {} steps, {} evaluations, \
         CPU {cpu:.3} s (predictor run time {:.3} s), final energy {:.3e} J",
        traj.steps,
        traj.evaluations,
        traj.run_time_s,
        last.kinetic_energy + last.potential_energy
    );
    assert_eq!(traj.samples.len(), 2001);
    assert!((last.t - 2000.0).abs() < 1e-9, "last sample at {}", last.t);
    // Achieved 3.938e-5 m.
    assert!(
        err <= 1e-4,
        "A01 position error {err:e} m > 1e-4 m (achieved 3.9e-5 m)"
    );
}
