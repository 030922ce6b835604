//! Forward dynamics without constraint rows, the linear-time path (`dynamics::tree`: ABA) beside
//! the dense one (CRBA, bias forces, the LTL factor of M and its solves: the multiplier form with
//! no rows), on generated chains of n revolute links (`tests/it/common/chain.rs`) and on the four
//! example-robot-data robots unconstrained (`robots/mod.rs`); and the multiplier form of the
//! chains held at both ends (three rows), without M (`dynamics::tree_multipliers`) and dense.
//! Ids `chain/<path>/<n>`, `robot/<path>/<name>` and `chain_loop/<path>/<n>` (path `linear` or
//! `dense`); `tools/chain_cost.py` runs it and writes the tables of docs/performance.md ("Cost
//! against the size of the tree").
//!
//! With `CHAIN_SCENES_DIR` set, the chains' URDF and scene files (`chain_<n>.urdf`,
//! `chain_<n>.yaml`, `chain_loop_<n>.yaml`) are written there first, for the tool to time the
//! whole `eval` process on.

#[path = "../tests/it/common/chain.rs"]
mod chain;
// Their contact sets and accelerations serve benches/dynamics.rs, not this bench.
#[allow(dead_code)]
mod robots;

use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::{
    Baumgarte, KktWorkspace, TreeKktWorkspace, TreeWorkspace, constrained_forward_dynamics,
    tree_constrained_forward_dynamics, tree_forward_dynamics,
};
use constraint_dynamics::{BaseType, Model, ModelOptions, System};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use std::hint::black_box;

/// The chains timed, and the largest on which the dense path (cubic on a chain) is timed.
const SIZES: [usize; 17] = [
    4, 8, 10, 12, 16, 24, 30, 32, 48, 64, 100, 128, 300, 1000, 2000, 3000, 5000,
];
const DENSE_MAX: usize = 1000;
/// The chains held at both ends that are timed.
const LOOP_SIZES: [usize; 7] = [10, 30, 100, 300, 1000, 3000, 5000];

fn chain_model(n: usize) -> Model {
    let opts = ModelOptions {
        base: BaseType::Fixed,
        ..Default::default()
    };
    Model::from_urdf_str(&chain::chain_urdf(n), "chain.urdf", &opts).expect("the chain loads")
}

fn write_scenes() {
    let Some(dir) = std::env::var_os("CHAIN_SCENES_DIR") else {
        return;
    };
    let dir = std::path::PathBuf::from(dir);
    std::fs::create_dir_all(&dir).expect("CHAIN_SCENES_DIR can be created");
    for n in SIZES {
        let urdf = format!("chain_{n}.urdf");
        std::fs::write(dir.join(&urdf), chain::chain_urdf(n)).expect("chain URDF written");
        std::fs::write(
            dir.join(format!("chain_{n}.yaml")),
            chain::chain_scene_yaml(n, &urdf),
        )
        .expect("chain scene written");
        std::fs::write(
            dir.join(format!("chain_loop_{n}.yaml")),
            chain::chain_loop_scene_yaml(n, &urdf),
        )
        .expect("chain loop scene written");
    }
}

/// The chain of n links held at both ends, as its scene file declares it.
fn chain_loop(n: usize) -> (Model, ConstraintSet) {
    let scene = chain::load_chain_scene(n, true);
    let sys = System::from_scene(&scene).expect("the chain loop's system");
    ((*scene.model).clone(), sys.constraints().clone())
}

/// Times the multiplier form of the held chain without M and (up to `DENSE_MAX`) dense.
fn loop_paths(c: &mut Criterion, n: usize) {
    let (m, set) = chain_loop(n);
    let q = chain::chain_q0(n);
    let v: Vec<f64> = (0..n).map(|k| (0.7 * k as f64).sin()).collect();
    let tau: Vec<f64> = (0..n).map(|k| 0.1 * (1.3 * k as f64).cos()).collect();
    let mut g = c.benchmark_group("chain_loop");
    if n >= 1000 {
        g.sample_size(10);
    }
    let mut data = Data::new(&m);
    let mut cd = ConstraintData::new(&m, &set);
    let mut ws = KktWorkspace::new(&m, &set);
    let mut tree = TreeKktWorkspace::new(&m);
    let opts = Baumgarte::default().into();
    let mut linear = || {
        tree_constrained_forward_dynamics(
            &m, &mut data, &set, &mut cd, &mut ws, &mut tree, &q, &v, &tau, opts,
        )
        .unwrap()
    };
    assert!(linear(), "the held chain takes the linear path");
    g.bench_function(BenchmarkId::new("linear", n), |b| b.iter(&mut linear));
    if n <= DENSE_MAX {
        let mut data = Data::new(&m);
        let mut cd = ConstraintData::new(&m, &set);
        let mut ws = KktWorkspace::new(&m, &set);
        g.bench_function(BenchmarkId::new("dense", n), |b| {
            b.iter(|| {
                constrained_forward_dynamics(
                    &m,
                    &mut data,
                    &set,
                    &mut cd,
                    &mut ws,
                    black_box(&q),
                    &v,
                    &tau,
                    opts,
                )
                .unwrap()
            })
        });
    }
    g.finish();
}

/// Times both paths on `m` at (q, v, τ) under `group/<path>/<param>`.
fn both_paths(
    c: &mut Criterion,
    group: &str,
    param: &str,
    m: &Model,
    (q, v, tau): (&[f64], &[f64], &[f64]),
    dense: bool,
) {
    let mut g = c.benchmark_group(group);
    if m.nv >= 1000 {
        g.sample_size(10);
    }
    let mut data = Data::new(m);
    let mut tree = TreeWorkspace::new(m);
    assert!(tree_forward_dynamics(m, &mut data, &mut tree, q, v, tau));
    g.bench_function(BenchmarkId::new("linear", param), |b| {
        b.iter(|| tree_forward_dynamics(m, &mut data, &mut tree, black_box(q), v, tau))
    });
    if dense {
        let set = ConstraintSet::default();
        let mut cd = ConstraintData::new(m, &set);
        let mut ws = KktWorkspace::new(m, &set);
        g.bench_function(BenchmarkId::new("dense", param), |b| {
            b.iter(|| {
                constrained_forward_dynamics(
                    m,
                    &mut data,
                    &set,
                    &mut cd,
                    &mut ws,
                    black_box(q),
                    v,
                    tau,
                    Baumgarte::default(),
                )
                .unwrap()
            })
        });
    }
    g.finish();
}

fn bench(c: &mut Criterion) {
    write_scenes();
    for n in SIZES {
        let m = chain_model(n);
        let q = chain::chain_q0(n);
        let v: Vec<f64> = (0..n).map(|k| (0.7 * k as f64).sin()).collect();
        let tau: Vec<f64> = (0..n).map(|k| 0.1 * (1.3 * k as f64).cos()).collect();
        both_paths(
            c,
            "chain",
            &n.to_string(),
            &m,
            (&q, &v, &tau),
            n <= DENSE_MAX,
        );
    }
    for k in &robots::all() {
        both_paths(c, "robot", k.name, &k.model, (&k.q, &k.v, &k.tau), true);
    }
    for n in LOOP_SIZES {
        loop_paths(c, n);
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(300))
        .measurement_time(std::time::Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
