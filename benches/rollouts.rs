//! Criterion benchmark of rollouts for sampling planners: N = 2000 command sequences × 56 steps
//! of 50 ms (Nav2 MPPI's defaults: batch_size 2000, time_steps 56, model_dt 0.05) on the
//! differential drive with its wheel-speed controllers (params/suite_diff_drive.yaml) at planner
//! settings: RK4 with projection, dt = control period = 5 ms (the wheel loop's time constant is
//! ≈ 10 ms; the scene's own rk4 at 1 ms control ticks costs 5× the steps), on 1
//! worker thread and on every core: sequences per second per core and the parallel efficiency
//! T₁ / (n T_n). `ROLLOUTS=N` sets another N.

#[path = "../tests/common/command_sequences.rs"]
mod command_sequences;

use command_sequences::sequences;
use constraint_dynamics::Scene;
use constraint_dynamics::predict::{
    DriftControl, Method, PredictionRequest, Predictor, RolloutOptions,
};
use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;

fn bench(c: &mut Criterion) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut scene = Scene::load(root.join("params/suite_diff_drive.yaml")).expect("scene");
    scene.file.actuators.control_period = Some(0.005);
    let predictor = Predictor::from_scene(&scene)
        .expect("predictor")
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.dt = 0.005;
            s.drift = DriftControl::Projection;
            // A planner scores thousands of rollouts: no error-estimate companion (2× the
            // work).
            s.error_estimate = false;
        })
        .expect("settings");
    let n: usize = std::env::var("ROLLOUTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let seqs = sequences(n, 56);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut group = c.benchmark_group("rollouts");
    group.sample_size(10);
    group.sampling_mode(SamplingMode::Flat);
    group.warm_up_time(std::time::Duration::from_millis(1));
    group.throughput(Throughput::Elements(n as u64));
    for threads in [1, cores] {
        let opts = RolloutOptions {
            step: 0.05,
            threads,
        };
        group.bench_function(format!("diff_drive/{n}x56x50ms/{threads}_threads"), |b| {
            b.iter(|| {
                let start = PredictionRequest::new(black_box(&scene.q0), &scene.v0);
                predictor.rollouts(&start, &seqs, opts).unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
