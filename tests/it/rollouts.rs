//! Rollouts for sampling planners: N command sequences from one state, spread over worker
//! threads, equal N single predictions bit for bit (each worker reuses one predictor, so this
//! also shows that a prediction leaves nothing behind that changes the next one).

use crate::command_sequences;
use crate::planner_settings;

use command_sequences::sequences;
use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{PredictionRequest, Predictor, RolloutOptions, Trajectory};
use std::path::PathBuf;

fn bits(t: &Trajectory) -> Vec<u64> {
    t.samples
        .iter()
        .flat_map(|s| {
            let forces = s
                .lambda
                .iter()
                .flatten()
                .chain(s.generalized_force.iter().flatten());
            std::iter::once(&s.t)
                .chain(&s.q)
                .chain(&s.v)
                .chain(&s.actuator_torque)
                .chain(forces)
                .chain([&s.kinetic_energy, &s.potential_energy, &s.position_residual])
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
        })
        .collect()
}

/// N rollouts of `predictor` equal N single predictions of fresh predictors from `make`.
fn check_bit_for_bit(scene: &Scene, make: impl Fn() -> Predictor, n: usize, what: &str) {
    let predictor = make();
    let (steps, step) = (6, 0.05);
    let seqs = sequences(n, steps);
    for (threads, forces) in [(2, false), (3, true), (1, false)] {
        let opts = RolloutOptions { step, threads };
        let start = PredictionRequest::new(&scene.q0, &scene.v0).forces(forces);
        let rolled = predictor.rollouts(&start, &seqs, opts).unwrap();
        assert_eq!(rolled.len(), n);
        for (k, (seq, r)) in seqs.iter().zip(&rolled).enumerate() {
            // The single prediction, from a fresh predictor each time.
            let mut single = make().with_settings(|s| s.sample_period = step).unwrap();
            let timed: Vec<(f64, Command)> = seq
                .iter()
                .enumerate()
                .map(|(i, c)| (i as f64 * step, c.clone()))
                .collect();
            let req = PredictionRequest::new(&scene.q0, &scene.v0)
                .commands(&timed)
                .horizon(steps as f64 * step)
                .forces(forces);
            let t = single.predict(&req).unwrap();
            assert_eq!(
                r.samples.len(),
                steps + 1,
                "{what} rollout {k}: one sample per step"
            );
            assert_eq!(
                (r.steps, r.evaluations),
                (t.steps, t.evaluations),
                "{what} rollout {k} ({threads} threads): work differs"
            );
            assert!(
                bits(r) == bits(&t),
                "{what} rollout {k} ({threads} threads) differs"
            );
            assert_eq!(r.samples[0].lambda.is_some(), forces);
        }
        // The commands took effect: the sequences end at different poses.
        let x_end: Vec<f64> = rolled.iter().map(|r| r.samples[steps].q[0]).collect();
        assert!(x_end.windows(2).any(|w| w[0] != w[1]), "{x_end:?}");
    }
}

#[test]
fn rollouts_equal_single_predictions_bit_for_bit() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(root.join("params/suite_diff_drive.yaml")).unwrap();
    check_bit_for_bit(
        &scene,
        || Predictor::from_scene(&scene).unwrap(),
        12,
        "scene",
    );
}

/// The planner's settings too: their continuous controllers keep a saturation state (frozen
/// integrals, skipped windup) that each prediction starts afresh.
#[test]
fn planner_rollouts_equal_single_predictions_bit_for_bit() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(root.join("params/suite_diff_drive.yaml")).unwrap();
    check_bit_for_bit(&scene, || planner_settings::planner(&scene), 24, "planner");
}

#[test]
fn rollouts_refuse_a_bad_step() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(root.join("params/suite_diff_drive.yaml")).unwrap();
    let predictor = Predictor::from_scene(&scene).unwrap();
    for step in [0.0, -0.05, f64::NAN] {
        let opts = RolloutOptions {
            step,
            ..Default::default()
        };
        let start = PredictionRequest::new(&scene.q0, &scene.v0);
        let e = predictor.rollouts(&start, &sequences(2, 3), opts);
        assert!(e.is_err(), "step {step} accepted");
    }
}

/// The batch's work is bounded as a whole, before running: RK4's work (12 evaluation costs per
/// step, the error-estimate companion counted) over 4 rollouts of 10 steps = 480 evaluation
/// costs of the model; max_work set to fit 2 rollouts refuses 4 and runs 2.
#[test]
fn rollouts_bound_the_batch_work() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut scene = Scene::load(root.join("params/suite_diff_drive.yaml")).unwrap();
    scene.file.actuators.control_period = Some(0.005);
    let cost = constraint_dynamics::limits::dense_evaluation_cost(&scene.model);
    // One rollout: 2 commands × 0.025 s = 10 steps × 12 = 120 costs; 2 rollouts 240.
    let predictor = Predictor::from_scene(&scene)
        .unwrap()
        .with_settings(|s| {
            s.method = constraint_dynamics::predict::Method::Rk4;
            s.dt = 0.005;
            s.max_work = 250.0 * cost;
        })
        .unwrap();
    let opts = RolloutOptions {
        step: 0.025,
        threads: 1,
    };
    let start = PredictionRequest::new(&scene.q0, &scene.v0);
    let e = predictor
        .rollouts(&start, &sequences(4, 2), opts)
        .unwrap_err();
    assert!(
        matches!(e, constraint_dynamics::Error::WorkLimit { .. }),
        "{e}"
    );
    let two = predictor.rollouts(&start, &sequences(2, 2), opts).unwrap();
    assert_eq!(two.len(), 2);
    assert_eq!(two[0].steps, 10);
}
