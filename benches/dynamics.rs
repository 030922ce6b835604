//! Criterion benchmarks of the rigid-body, constrained and derivative algorithms on the robots
//! that compiled Pinocchio is timed on by `../shared/tools/anchors/cpp/bench_pin.cpp` (ur5 with
//! tool0 held, panda with its fingers locked and panda_hand_tcp held, solo12 on four point feet,
//! talos_reduced on two 6D soles; benches/robots.rs). `tools/bench.py` runs both in one run
//! and writes docs/bench.md; ids are `robot/algorithm`.
//!
//! Each id computes what the Pinocchio call it is compared with returns:
//! - `fk`: placements, twists and accelerations (`forwardKinematics(q, v, a)`);
//! - `rnea_derivatives`: ∂τ/∂q, ∂τ/∂v and M (`computeRNEADerivatives` fills M too, as ours
//!   does);
//! - `aba_derivatives`: q̈, ∂q̈/∂q, ∂q̈/∂v, M⁻¹ (`computeABADerivatives`);
//! - `constrained_derivatives`: the solve and ∂(q̈, λ)/∂(q, v, τ) (`constraintDynamics` followed by
//!   `computeConstraintDynamicsDerivatives`).

mod robots;

use constraint_dynamics::algorithm::*;
use constraint_dynamics::constraints::ConstraintData;
use constraint_dynamics::derivatives::{
    DerivativeData, aba_derivatives, constrained_dynamics_derivatives, rnea_derivatives,
};
use constraint_dynamics::dynamics::{Baumgarte, KktWorkspace, constrained_forward_dynamics};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    for k in &robots::all() {
        let (m, q, v, a, tau) = (&k.model, &k.q, &k.v, &k.a, &k.tau);
        let mut d = Data::new(m);
        let id = |algo: &str| format!("{}/{algo}", k.name);
        c.bench_function(&id("fk"), |b| {
            b.iter(|| forward_kinematics(m, &mut d, black_box(q), black_box(v), black_box(a)))
        });
        c.bench_function(&id("rnea"), |b| {
            b.iter(|| {
                rnea(m, &mut d, black_box(q), black_box(v), black_box(a));
            })
        });
        c.bench_function(&id("crba"), |b| {
            b.iter(|| {
                crba(m, &mut d, black_box(q));
            })
        });
        c.bench_function(&id("aba"), |b| {
            b.iter(|| {
                aba(m, &mut d, black_box(q), black_box(v), black_box(tau));
            })
        });
        let mut cd = ConstraintData::new(m, &k.set);
        let mut ws = KktWorkspace::new(m, &k.set);
        c.bench_function(&id("constraint_terms"), |b| {
            b.iter(|| {
                k.set
                    .evaluate(m, &mut d, &mut cd, 0.0, black_box(q), black_box(v))
            })
        });
        c.bench_function(&id("constrained_dynamics"), |b| {
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
        let mut dd = DerivativeData::new(m, k.set.nrows);
        c.bench_function(&id("rnea_derivatives"), |b| {
            b.iter(|| {
                rnea_derivatives(m, &mut d, &mut dd, black_box(q), black_box(v), black_box(a));
            })
        });
        c.bench_function(&id("aba_derivatives"), |b| {
            b.iter(|| {
                aba_derivatives(
                    m,
                    &mut d,
                    &mut dd,
                    black_box(q),
                    black_box(v),
                    black_box(tau),
                )
                .unwrap();
            })
        });
        c.bench_function(&id("constrained_derivatives"), |b| {
            b.iter(|| {
                constrained_dynamics_derivatives(
                    m,
                    &mut d,
                    &k.set,
                    &mut cd,
                    &mut ws,
                    &mut dd,
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
