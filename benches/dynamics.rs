//! Criterion benchmarks of the rigid-body and constrained algorithms on the reference robots
//! (UR5: 6 DOF, end-effector point held, 3 rows; Solo12 on a free-flyer: 18 DOF, 4 feet, 12 rows).
//! `tools/bench_vs_pinocchio.py` runs these beside Pinocchio and prints the ratios.

#[path = "../tests/common/mod.rs"]
mod common;

use constraint_dynamics::Model;
use constraint_dynamics::algorithm::*;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::{Baumgarte, KktWorkspace, constrained_forward_dynamics};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

struct Case {
    name: &'static str,
    model: Model,
    q: Vec<f64>,
    v: Vec<f64>,
    tau: Vec<f64>,
    set: ConstraintSet,
}

/// A reference case's model, state 2 and its constraints (shared with the tests).
fn load(name: &'static str, case: &str) -> Case {
    let json = common::load_case(case);
    let model = common::case_model(&json);
    let st = &json["states"][2];
    let q = common::vecf(&st["q"]);
    let set = ConstraintSet::new(&model, &common::specs_for(&json, st), &q).expect("constraints");
    Case {
        name,
        q,
        v: common::vecf(&st["qd"]),
        tau: common::vecf(&st["tau"]),
        model,
        set,
    }
}

fn bench(c: &mut Criterion) {
    let cases = [
        load("ur5", "ur5_ee_point"),
        load("solo12", "solo12_four_feet"),
    ];
    for k in &cases {
        let (m, q, v, tau) = (&k.model, &k.q, &k.v, &k.tau);
        let mut d = Data::new(m);
        c.bench_function(&format!("{}/rnea", k.name), |b| {
            b.iter(|| {
                rnea(m, &mut d, black_box(q), black_box(v), black_box(tau));
            })
        });
        c.bench_function(&format!("{}/crba", k.name), |b| {
            b.iter(|| {
                crba(m, &mut d, black_box(q));
            })
        });
        c.bench_function(&format!("{}/aba", k.name), |b| {
            b.iter(|| {
                aba(m, &mut d, black_box(q), black_box(v), black_box(tau));
            })
        });
        let mut cd = ConstraintData::new(m, &k.set);
        let mut ws = KktWorkspace::new(m, &k.set);
        c.bench_function(&format!("{}/constraint_terms", k.name), |b| {
            b.iter(|| {
                k.set
                    .evaluate(m, &mut d, &mut cd, black_box(q), black_box(v))
            })
        });
        c.bench_function(&format!("{}/constrained_dynamics", k.name), |b| {
            b.iter(|| {
                constrained_forward_dynamics(
                    m,
                    &mut d,
                    &k.set,
                    &mut cd,
                    &mut ws,
                    black_box(q),
                    black_box(v),
                    black_box(tau),
                    Baumgarte::default(),
                )
                .unwrap();
            })
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(2));
    targets = bench
}
criterion_main!(benches);
