//! The stepping loop allocates nothing: with a counting allocator, a prediction with 4× the steps
//! (and the same samples) makes exactly as many allocations — every method, with projection, on a
//! constrained scene (fourbar, full-rank loop) and with force elements (stiff chain); and RK4 with
//! projection in both formulations on the rank-deficient and rolling scenes (diff drive, mobile
//! manipulator, rolling disk). The error estimate's companion run (two lanes sized once) is part
//! of every prediction, so it is covered.

use constraint_dynamics::Scene;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::predict::{DriftControl, Method, Predictor};
use std::path::PathBuf;

#[path = "common/counting_alloc.rs"]
mod counting_alloc;
use counting_alloc::allocations;

/// Allocations of one prediction over `horizon` with two samples (t = 0 and the end).
fn prediction_allocations(p: &mut Predictor, sc: &Scene, horizon: f64) -> usize {
    p.settings.sample_period = horizon;
    let mut t = None;
    let n = allocations(|| t = Some(p.predict(&sc.q0, &sc.v0, &[], horizon).unwrap()));
    let t = t.unwrap();
    assert_eq!(t.samples.len(), 2);
    // The companion ran (its evaluations counted) and gave a finite estimate.
    assert!(t.estimate_evaluations > 0);
    assert!(
        t.samples
            .iter()
            .all(|s| s.error_estimate.is_some_and(f64::is_finite))
    );
    n
}

#[test]
fn stepping_allocates_nothing_per_step() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let cases = [
        ("params/fourbar.yaml", 1e-3),
        ("params/report/spring_chain_stiff.yaml", 1e-5),
    ];
    for (rel, dt) in cases {
        let sc = Scene::load(root.join(rel)).unwrap();
        for method in [
            Method::SemiImplicitEuler,
            Method::Rk4,
            Method::Dopri5,
            Method::Sdirk2,
        ] {
            let mut p = Predictor::from_scene(&sc).unwrap();
            p.settings.method = method;
            p.settings.dt = dt;
            p.settings.drift = DriftControl::Projection;
            // SIE at 1 ms on the fourbar errs by 2.6e-3 rad over 0.1 s (its estimate says so);
            // this test counts allocations, not digits.
            p.settings.max_error = f64::INFINITY;
            let h = 100.0 * dt;
            prediction_allocations(&mut p, &sc, h); // warm-up
            let (short, long) = (
                prediction_allocations(&mut p, &sc, h),
                prediction_allocations(&mut p, &sc, 4.0 * h),
            );
            println!(
                "{rel} {method:?}: {short} allocations over {h} s, {long} over {} s",
                4.0 * h
            );
            assert_eq!(short, long, "{rel} {method:?}: the steps allocate");
        }
    }
}

#[test]
fn stepping_allocates_nothing_per_step_on_rolling_scenes() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    for rel in [
        "params/report/diff_drive_coasting.yaml",
        "params/mobile_manipulator.yaml",
        "params/report/rolling_disk.yaml",
    ] {
        let sc = Scene::load(root.join(rel)).unwrap();
        for formulation in [Formulation::Multipliers, Formulation::Embedded] {
            let mut p = Predictor::from_scene(&sc).unwrap();
            p.sys.formulation = formulation;
            p.settings.method = Method::Rk4;
            p.settings.dt = 1e-3;
            p.settings.drift = DriftControl::Projection;
            let h = 0.05;
            prediction_allocations(&mut p, &sc, h); // warm-up
            let (short, long) = (
                prediction_allocations(&mut p, &sc, h),
                prediction_allocations(&mut p, &sc, 4.0 * h),
            );
            println!(
                "{rel} {formulation:?}: {short} allocations over {h} s, {long} over {} s",
                4.0 * h
            );
            assert_eq!(short, long, "{rel} {formulation:?}: the steps allocate");
        }
    }
}
