//! The covariance on its worker thread (src/predict/covariance/worker.rs) is the covariance
//! propagated inline, to the bit: the same samples, the same P at every sample, the same
//! linearizations — and the same errors, whichever side meets one. (Its accuracy against Monte
//! Carlo is tests/it/covariance.rs, which runs on the worker wherever there are two cores.)

use crate::common;
use common::{repo_dir, turning_with_arm_held};
use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::error::Error;
use constraint_dynamics::predict::{IntegrationSettings, PredictionRequest, Predictor, Trajectory};
use nalgebra::DMatrix;

/// The scene's prediction from its initial state with start covariance σ² I, inline and on
/// the worker.
fn both(
    scene: &str,
    sigma: f64,
    commands: &[(f64, Command)],
    horizon: f64,
    tune: impl Fn(&mut IntegrationSettings),
) -> [Result<Trajectory, Error>; 2] {
    assert!(
        std::thread::available_parallelism().is_ok_and(|n| n.get() > 1),
        "one core: the worker would not run, and this test would compare inline with inline"
    );
    let scene = Scene::load(repo_dir().join("params").join(scene)).unwrap();
    [false, true].map(|parallel| {
        let mut p = Predictor::from_scene(&scene)
            .unwrap()
            .with_settings(&tune)
            .unwrap()
            .with_parallel_covariance(parallel);
        let nv = p.model().nv;
        let p0 = DMatrix::identity(2 * nv, 2 * nv) * (sigma * sigma);
        let req = PredictionRequest::new(&scene.q0, &scene.v0)
            .commands(commands)
            .horizon(horizon)
            .covariance(&p0);
        p.predict(&req)
    })
}

fn assert_same(inline: &Trajectory, worker: &Trajectory) {
    assert_eq!(inline.samples.len(), worker.samples.len());
    assert_eq!(
        inline.covariance_linearizations,
        worker.covariance_linearizations
    );
    assert!(inline.covariance_linearizations > 0);
    for (a, b) in inline.samples.iter().zip(&worker.samples) {
        assert_eq!(a.t.to_bits(), b.t.to_bits());
        assert_eq!(a.q, b.q, "t = {}", a.t);
        let (pa, pb) = (a.covariance.as_ref(), b.covariance.as_ref());
        let (pa, pb) = (pa.expect("inline P"), pb.expect("worker's P"));
        for (ra, rb) in pa.iter().zip(pb) {
            for (x, y) in ra.iter().zip(rb) {
                assert_eq!(x.to_bits(), y.to_bits(), "P at t = {}: {x:e} vs {y:e}", a.t);
            }
        }
    }
}

/// The suite's mobile manipulator under its controllers (a stiff wrist: one linearization per
/// step), samples every 20 ms.
#[test]
fn controlled_mobile_manipulator_worker_equals_inline() {
    let cmd = turning_with_arm_held();
    let [a, b] = both(
        "suite_mobile_manipulator.yaml",
        1e-3,
        &[(0.0, cmd)],
        0.3,
        |_| {},
    );
    let (a, b) = (a.unwrap(), b.unwrap());
    assert_same(&a, &b);
    assert_eq!(a.samples.len(), 16);
}

/// Bricard's mechanism, whose closure has a redundant row that the linearized steps' stages
/// make disagree: they take the least-squares multipliers on the worker's clone of the system
/// as inline, where the prediction's own stages ran on the same system just before.
#[test]
fn redundant_closure_worker_equals_inline() {
    let [a, b] = both("report/bricard_a04.yaml", 1e-3, &[], 0.3, |_| {});
    let (a, b) = (a.unwrap(), b.unwrap());
    assert_same(&a, &b);
    assert_eq!(a.samples.len(), 31);
}

/// Samples 100 ms apart: records fill up (32 steps) and go to the worker between samples.
#[test]
fn full_records_between_samples_worker_equals_inline() {
    let [a, b] = both("diff_drive.yaml", 1e-3, &[], 0.5, |s| {
        s.sample_period = 0.1;
    });
    let (a, b) = (a.unwrap(), b.unwrap());
    assert_same(&a, &b);
    assert_eq!(a.samples.len(), 6);
}

/// A covariance that overflows (a start σ of 1e154 m: σ² ≈ 1e308) is refused at the first
/// sample after it overflows, with the same message either way.
#[test]
fn an_overflowing_covariance_is_the_same_error_on_the_worker() {
    let [a, b] = both("diff_drive.yaml", 1e154, &[], 0.5, |_| {});
    let (a, b) = (a.unwrap_err().to_string(), b.unwrap_err().to_string());
    assert!(a.contains("covariance overflowed"), "{a}");
    assert_eq!(a, b);
}

/// An error of the prediction itself while the worker holds a record (an error estimate above
/// `max_error` at the first sample, 2.4e-16 m against 1e-17, without `adapt`) ends the run with
/// that error, without waiting forever.
#[test]
fn a_prediction_error_with_the_worker_busy_is_the_predictions() {
    let [a, b] = both("vertical_disk.yaml", 1e-3, &[], 0.5, |s| {
        s.max_error = 1e-17;
        s.adapt = false;
    });
    let (a, b) = (a.unwrap_err().to_string(), b.unwrap_err().to_string());
    assert!(a.contains("error estimate"), "{a}");
    assert_eq!(a, b);
}
