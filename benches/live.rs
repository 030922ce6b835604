//! Criterion benchmark of the live prediction on the suite's default scene
//! (params/suite_mobile_manipulator.yaml) with continuous controllers and ROS2 at 20 ms, error
//! estimate on: the predictor node's tick (1 s with a start covariance, as /odom gives one) and a
//! planner's 2 s `Predict` under a turning command with its arm held; and `predict/2s_brisk`, the
//! 2 s prediction under brisk turning commands — (0.4, 0), (0.5, 0.6) at 0.5 s, (0.3, −0.8) at
//! 1.2 s, (0, 0.3) at 1.7 s — arm held, a sample every 0.1 s. Their accuracy against the held
//! reference is asserted in tests/it/live_prediction.rs and tests/it/error_kinds.rs.

use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{CovarianceSamples, PredictionRequest, Predictor};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;

fn bench(c: &mut Criterion) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(root.join("params/suite_mobile_manipulator.yaml")).expect("scene");
    let mut predictor = Predictor::from_scene(&scene).expect("predictor");
    let mut cmd = Command {
        base_twist: Some([0.3, 0.5]),
        ..Default::default()
    };
    for n in [
        "arm_shoulder_yaw",
        "arm_shoulder_pitch",
        "arm_elbow",
        "arm_wrist",
    ] {
        let i = predictor
            .model()
            .q_names
            .iter()
            .position(|x| x == n)
            .expect("joint");
        cmd.joint_position.insert(n.into(), scene.q0[i]);
    }
    let cmds = [(0.0, cmd)];
    let nv = predictor.model().nv;
    let mut p0 = nalgebra::DMatrix::zeros(2 * nv, 2 * nv);
    for i in [0, 1, 2, nv, nv + 1, nv + 2] {
        p0[(i, i)] = 1e-4;
    }
    let mut group = c.benchmark_group("live");
    group.bench_function("tick/1s_covariance", |b| {
        b.iter(|| {
            let req = PredictionRequest::new(black_box(&scene.q0), &scene.v0)
                .commands(&cmds)
                .covariance(&p0)
                .covariance_samples(CovarianceSamples::Last);
            predictor.predict(&req).unwrap()
        })
    });
    group.bench_function("predict/2s", |b| {
        b.iter(|| {
            let req = PredictionRequest::new(black_box(&scene.q0), &scene.v0)
                .commands(&cmds)
                .horizon(2.0);
            predictor.predict(&req).unwrap()
        })
    });
    let brisk: Vec<(f64, Command)> = [
        (0.0, [0.4, 0.0]),
        (0.5, [0.5, 0.6]),
        (1.2, [0.3, -0.8]),
        (1.7, [0.0, 0.3]),
    ]
    .into_iter()
    .map(|(t, tw)| {
        let mut c = cmds[0].1.clone();
        c.base_twist = Some(tw);
        (t, c)
    })
    .collect();
    let mut sparse = Predictor::from_scene(&scene)
        .expect("predictor")
        .with_settings(|s| s.sample_period = 0.1)
        .expect("settings");
    group.bench_function("predict/2s_brisk", |b| {
        b.iter(|| {
            let req = PredictionRequest::new(black_box(&scene.q0), &scene.v0)
                .commands(&brisk)
                .horizon(2.0);
            sparse.predict(&req).unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
