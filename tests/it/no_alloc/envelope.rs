//! The acceleration envelope (four cone programs) allocates nothing after its first call outside
//! Clarabel's own solve: the solver is built once and updated in place, the results are
//! preallocated. Clarabel's `solve` rebuilds its timers' nested maps at every call (a fixed
//! number of allocations per solve, counted here on a two-variable cone program).

use crate::common;
use common::*;
use constraint_dynamics::envelope::{EnvelopeData, EnvelopeModel, acceleration_envelope};
use constraint_dynamics::{Scene, System};

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SecondOrderConeT,
};

use crate::counting_alloc;
use counting_alloc::allocations;

/// Allocations of one `solve` of a Clarabel solver that has solved before (max x₀ subject to
/// ‖x‖ ≤ 1, x₁ ≥ −1).
pub(crate) fn clarabel_solve_allocations() -> usize {
    let p = CscMatrix::new(2, 2, vec![0, 0, 0], vec![], vec![]);
    let a = CscMatrix::new(4, 2, vec![0, 1, 3], vec![1, 0, 2], vec![-1.0, -1.0, -1.0]);
    let cones = [NonnegativeConeT(1), SecondOrderConeT(3)];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .input_sparse_dropzeros(false)
        .build()
        .unwrap();
    let (q, b) = ([-1.0, 0.0], [1.0, 1.0, 0.0, 0.0]);
    let mut s = DefaultSolver::new(&p, &q, &a, &b, &cones, settings).unwrap();
    s.solve();
    let n = allocations(|| s.solve());
    assert!((s.solution.x[0] - 1.0f64).abs() < 1e-6);
    n
}

#[test]
fn envelope_allocates_nothing_outside_clarabels_solve_after_the_first_call() {
    let per_solve = clarabel_solve_allocations();
    println!("Clarabel's solve: {per_solve} allocations");
    for name in [
        "tests/data/cart_tall_mass.yaml",
        "params/mobile_manipulator_floating.yaml",
        "params/mobile_manipulator.yaml",
        "params/diff_drive.yaml",
    ] {
        let scene = Scene::load(repo_dir().join(name)).unwrap();
        let mut sys = System::from_scene(&scene).unwrap();
        let em = EnvelopeModel::from_scene(&scene, &sys).unwrap();
        let mut ed = EnvelopeData::new(&em);
        let zero = vec![0.0; sys.model().nv];
        let (q, v) = (scene.q0.clone(), scene.v0.clone());
        acceleration_envelope(&mut sys, &em, &mut ed, &q, &v, &zero).unwrap();
        // A second state (the arm or the base moved) reuses the solver.
        let mut q2 = q.clone();
        let last = q2.len() - 1;
        q2[last] += 0.1;
        let n = allocations(|| {
            acceleration_envelope(&mut sys, &em, &mut ed, &q2, &v, &zero).unwrap();
            acceleration_envelope(&mut sys, &em, &mut ed, &q, &v, &zero).unwrap();
        });
        // Two envelopes, four solves each.
        assert_eq!(n, 8 * per_solve, "{name}: the envelope allocates");
    }
}
