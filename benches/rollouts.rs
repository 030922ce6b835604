//! Criterion benchmark of rollouts for sampling planners: N = 1000 command sequences × 56 steps
//! of 50 ms (Nav2 MPPI's time_steps and model_dt) on the differential drive
//! (params/suite_diff_drive.yaml) at the scene's `rollouts:` settings (continuous wheel
//! controllers with anti-windup, ROS2 at 16.7 ms on one F per rollout, projection, no
//! error-estimate companion; `tests/it/rollouts_planner.rs` holds them to 1 cm and 0.01 rad of the
//! scene's 1 ms controllers), on 1 worker thread and on every core. `ROLLOUTS=N` sets another N.

#[path = "../tests/it/common/command_sequences.rs"]
mod command_sequences;
#[path = "../tests/it/common/planner_settings.rs"]
mod planner_settings;

use command_sequences::sequences;
use constraint_dynamics::Scene;
use constraint_dynamics::predict::{PredictionRequest, RolloutOptions};
use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;

fn bench(c: &mut Criterion) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(root.join("params/suite_diff_drive.yaml")).expect("scene");
    let predictor = planner_settings::planner(&scene);
    let n: usize = std::env::var("ROLLOUTS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1000);
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
