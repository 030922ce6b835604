//! SDIRK2's step count and Jacobian reuse: a fixed-step run takes exactly the steps asked for,
//! and the Newton matrix is kept across steps while Newton converges (refreshed only on failure
//! or slow convergence), measured on the stiff spring chain (1e6–1e8 N/m on 0.1 kg).

use crate::common;
use constraint_dynamics::predict::{DriftControl, Method, PredictionRequest, Predictor};

/// SDIRK2 on the stiff spring chain (`common::very_stiff_chain`).
fn very_stiff_chain() -> Predictor {
    let (mut sc, spec) = common::very_stiff_chain();
    sc.file.forces = spec;
    Predictor::from_scene(&sc)
        .unwrap()
        .with_settings(|s| {
            s.method = Method::Sdirk2;
            s.drift = DriftControl::None;
            // At 1e-5 s (dt·ω = 0.45 for the fastest mode) SDIRK2 damps the stiff modes: its
            // error estimate (1.4e-3 m) is over the default bound. These tests count steps and
            // evaluations.
            s.max_error = f64::INFINITY;
        })
        .unwrap()
}

/// 30 000 steps asked (0.3 s at 1e-5 s, one sample at the end, and 30 samples) → 30 000 taken.
#[test]
fn sdirk2_takes_exactly_the_steps_asked_for() {
    for sample_period in [0.3, 0.01] {
        let mut p = very_stiff_chain()
            .with_settings(|s| {
                s.dt = 1e-5;
                s.sample_period = sample_period;
            })
            .unwrap();
        let q0 = vec![0.002, -0.001, 0.0005, 0.0, 0.001];
        let t = p
            .predict(&PredictionRequest::new(&q0, &[0.0; 5]).horizon(0.3))
            .unwrap();
        println!(
            "sdirk2 stiff chain, 0.3 s at 1e-5 s, samples every {sample_period} s: {} steps, {} \
             evaluations ({:.2} per step), {} in the error estimate's companion, {:.3} s in all",
            t.steps,
            t.evaluations,
            t.evaluations as f64 / t.steps as f64,
            t.estimate_evaluations,
            t.run_time_s
        );
        assert_eq!(t.steps, 30_000); // exactly as asked: rounding of t adds none
        // One q̈ at the step's start and two Newton iterations per stage: 5 per step, plus one
        // Jacobian (2nv = 10) for the whole run.
        assert!(t.evaluations <= 5 * 30_000 + 10, "{}", t.evaluations);
    }
}
