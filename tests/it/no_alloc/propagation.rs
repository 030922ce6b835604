//! The stepping loop allocates nothing: with a counting allocator, a prediction with 4× the steps
//! (and the same samples) makes exactly as many allocations — every method, with projection, on a
//! constrained scene (fourbar, full-rank loop) and with force elements (stiff chain); and RK4 with
//! projection in both formulations on the rank-deficient and rolling scenes (diff drive, mobile
//! manipulator, rolling disk); closed-loop actuators following a command with a propagated
//! covariance (a control tick must not clone the command's maps or build a target list). The
//! error estimate's companion run (two lanes sized once) is part of every prediction, so it is
//! covered.

use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::predict::{
    DriftControl, IntegrationOverrides, Method, PredictionRequest, Predictor, Trajectory,
};
use nalgebra::DMatrix;
use std::path::PathBuf;

use crate::counting_alloc;
use counting_alloc::allocations;

/// Allocations of one prediction over `horizon` with two samples (t = 0 and the end).
fn prediction_allocations(p: &mut Predictor, sc: &Scene, horizon: f64) -> usize {
    let req = PredictionRequest::new(&sc.q0, &sc.v0)
        .horizon(horizon)
        .integration(sample_every(horizon));
    let mut t = None;
    let n = allocations(|| t = Some(p.predict(&req).unwrap()));
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

/// Allocations of one prediction under `commands` over `horizon` with a start covariance `p0`
/// and two samples (t = 0 and the end), and the trajectory.
fn covariance_prediction_allocations(
    p: &mut Predictor,
    sc: &Scene,
    commands: &[(f64, Command)],
    p0: &DMatrix<f64>,
    horizon: f64,
) -> (usize, Trajectory) {
    let req = PredictionRequest::new(&sc.q0, &sc.v0)
        .commands(commands)
        .horizon(horizon)
        .covariance(p0)
        .integration(sample_every(horizon));
    let mut t = None;
    let n = allocations(|| t = Some(p.predict(&req).unwrap()));
    let t = t.unwrap();
    assert_eq!(t.samples.len(), 2);
    (n, t)
}

/// This call's samples every `period` [s].
fn sample_every(period: f64) -> IntegrationOverrides {
    IntegrationOverrides {
        sample_period: Some(period),
        ..Default::default()
    }
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
            Method::Dop853,
            Method::Sdirk2,
            Method::Radau5,
        ] {
            let mut p = Predictor::from_scene(&sc)
                .unwrap()
                .with_settings(|s| {
                    s.method = method;
                    s.dt = dt;
                    s.drift = DriftControl::Projection;
                    // SIE at 1 ms on the fourbar errs by 2.6e-3 rad over 0.1 s (its estimate
                    // says so); this test counts allocations, not digits.
                    s.max_error = f64::INFINITY;
                })
                .unwrap();
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
        let mut sc = Scene::load(root.join(rel)).unwrap();
        for formulation in [Formulation::Multipliers, Formulation::Embedded] {
            sc.file.dynamics.formulation = formulation;
            let mut p = Predictor::from_scene(&sc)
                .unwrap()
                .with_settings(|s| {
                    s.method = Method::Rk4;
                    s.dt = 1e-3;
                    s.drift = DriftControl::Projection;
                })
                .unwrap();
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

/// Closed-loop actuators (a control tick every 1 ms: the diff drive's PI wheel controllers and
/// the arm's PD joints following a command) and a propagated covariance (its linearized steps and
/// constraint projection): 4× the ticks and steps, the same allocations — inline and on the
/// covariance's worker thread (its records handed over every 32 steps and at samples).
#[test]
fn actuated_prediction_with_covariance_allocates_nothing_per_step() {
    for parallel in [false, true] {
        actuated_with_covariance(parallel);
    }
}

fn actuated_with_covariance(parallel: bool) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let sc = Scene::load(root.join("params/suite_mobile_manipulator.yaml")).unwrap();
    let mut p = Predictor::from_scene(&sc)
        .unwrap()
        .with_parallel_covariance(parallel)
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.dt = 1e-3;
            s.drift = DriftControl::Projection;
        })
        .unwrap();
    let n = 2 * p.model().nv;
    let p0 = nalgebra::DMatrix::identity(n, n) * 1e-6;
    let mut cmd = Command {
        base_twist: Some([0.3, 0.2]),
        ..Default::default()
    };
    cmd.joint_position.insert("arm_elbow".into(), 0.8);
    let commands = [(0.0, cmd)];
    let mut run = |h: f64| {
        let (n, t) = covariance_prediction_allocations(&mut p, &sc, &commands, &p0, h);
        assert!(t.samples.iter().all(|s| s.covariance.is_some()));
        n
    };
    let h = 0.05;
    run(h); // warm-up
    let (short, long) = (run(h), run(4.0 * h));
    println!(
        "actuated mobile manipulator with covariance (worker: {parallel}): {short} allocations \
         over {h} s, {long} over {} s",
        4.0 * h
    );
    assert_eq!(short, long, "the control ticks or the covariance allocate");
}

/// Radau5 on the soft-floor robot (its tyres' forces differentiated at every stage) with a
/// propagated covariance: its steps covered by ROS2 substeps of the variational equation, their
/// A and B composed (src/predict/covariance/chunks.rs). 4× the horizon, the same allocations.
#[test]
fn radau5_with_covariance_allocates_nothing_per_step() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let sc = Scene::load(root.join("params/mobile_manipulator_soft_floor.yaml")).unwrap();
    let mut p = Predictor::from_scene(&sc)
        .unwrap()
        .with_parallel_covariance(false)
        .with_settings(|s| assert_eq!(s.method, Method::Radau5))
        .unwrap();
    let n = 2 * p.model().nv;
    let p0 = nalgebra::DMatrix::identity(n, n) * 1e-6;
    let commands = [(0.0, crate::common::turning_with_arm_held())];
    let mut run = |h: f64| {
        let (n, t) = covariance_prediction_allocations(&mut p, &sc, &commands, &p0, h);
        assert!(t.samples.iter().all(|s| s.covariance.is_some()));
        n
    };
    let h = 0.1;
    run(h); // warm-up
    let (short, long) = (run(h), run(4.0 * h));
    println!(
        "soft floor, radau5 with covariance: {short} allocations over {h} s, {long} over {} s",
        4.0 * h
    );
    assert_eq!(short, long, "Radau5's steps or their covariance allocate");
}

/// With forces, the contacts are judged at the samples only: the cart pushed by its torque ramp
/// (tests/data/cart_torque_ramp.yaml, two rolling wheels and a unilateral caster), 4× the steps
/// and the same two samples, the same allocations.
#[test]
fn judging_contacts_allocates_nothing_per_step() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let sc = Scene::load(root.join("tests/data/cart_torque_ramp.yaml")).unwrap();
    let mut p = Predictor::from_scene(&sc).unwrap();
    let mut run = |h: f64| {
        let req = PredictionRequest::new(&sc.q0, &sc.v0)
            .horizon(h)
            .forces(true)
            .integration(sample_every(h));
        let mut t = None;
        let n = allocations(|| t = Some(p.predict(&req).unwrap()));
        let t = t.unwrap();
        assert_eq!(t.samples.len(), 2);
        assert!(t.samples.iter().all(|s| s.contacts.is_some()));
        assert!(t.contact_check.is_some());
        n
    };
    let h = 0.05;
    run(h); // warm-up
    let (short, long) = (run(h), run(4.0 * h));
    println!(
        "cart with forces and contacts judged: {short} allocations over {h} s, {long} over {} s",
        4.0 * h
    );
    assert_eq!(short, long, "judging the contacts allocates per step");
}

/// The suite's live settings (continuous controllers, ROS2 with `jacobian_spans: 5`, the
/// covariance on the steps' own F) under a command that saturates both wheels (their targets
/// jump by 17 and 11 rad/s against kp 1 N·m·s/rad and 5 N·m): the anti-windup's probes and cut
/// spans, 4× the steps, the same allocations.
#[test]
fn live_settings_with_saturated_wheels_allocate_nothing_per_step() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let sc = Scene::load(root.join("params/suite_mobile_manipulator.yaml")).unwrap();
    let mut p = Predictor::from_scene(&sc).unwrap();
    let n = 2 * p.model().nv;
    let p0 = nalgebra::DMatrix::identity(n, n) * 1e-6;
    // The arm held where it starts, as the predictor node commands it.
    let mut cmd = Command {
        base_twist: Some([-0.5, 1.0]),
        ..Default::default()
    };
    for c in &sc.file.actuators.position {
        let iq = sc.model.q_index(&c.joint).unwrap();
        cmd.joint_position.insert(c.joint.clone(), sc.q0[iq]);
    }
    let commands = [(0.0, cmd)];
    let mut run = |h: f64| {
        let (n, t) = covariance_prediction_allocations(&mut p, &sc, &commands, &p0, h);
        (n, t.steps)
    };
    let h = 0.2;
    run(h); // warm-up
    let ((short, steps_short), (long, steps_long)) = (run(h), run(4.0 * h));
    println!(
        "live settings, saturated wheels: {short} allocations over {h} s ({steps_short} steps), \
         {long} over {} s ({steps_long} steps)",
        4.0 * h
    );
    // 10 steps of 20 ms, more where a span is cut at a wheel's return inside its effort.
    assert!(steps_short > 10, "no span was cut: {steps_short} steps");
    assert_eq!(
        short, long,
        "the anti-windup's probes or cut spans allocate"
    );
}
