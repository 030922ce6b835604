//! The continuous controllers' conditional anti-windup against its closed form: a flywheel
//! (tests/data/flywheel_pi.yaml: I = 0.01 kg·m² about its axle, effort E = 1.2 N·m, a PI velocity
//! controller kp = 0.5 N·m·s/rad, ki = 5 N·m/rad, `hold: continuous`) commanded ω* = 10 rad/s
//! from rest.
//!
//! The motor saturates at once (kp ω* = 5 N·m > E) and the integral z = ∫(ω* − ω) dt holds its
//! value there, 0: ω = E t / I until kp (ω* − ω) = E, at t₁ = (ω* − E/kp) I / E. Then z resumes
//! from 0 and e = ω* − ω obeys I ė = −(kp e + ki z), ż = e: z'' + (kp/I) z' + (ki/I) z = 0 with
//! z(t₁) = 0, z'(t₁) = E/kp. The roots s₁,₂ of s² + (kp/I) s + ki/I are real here, so with
//! τ = t − t₁: z = A (e^{s₁τ} − e^{s₂τ}), A = (E/kp) / (s₁ − s₂), ω = ω* − z',
//! q = q(t₁) + ω* τ − z. A controller that kept integrating while saturated would enter the
//! second phase with z = ω* t₁ − E t₁² / (2I) instead of 0, and overshoot the target.
use crate::common;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{PredictionRequest, Predictor};

const I: f64 = 0.01;
const E: f64 = 1.2;
const KP: f64 = 0.5;
const KI: f64 = 5.0;
const TARGET: f64 = 10.0;

/// The closed form (module doc): (q [rad], ω [rad/s]) at t [s].
fn closed_form(t: f64) -> (f64, f64) {
    let t1 = (TARGET - E / KP) * I / E;
    if t <= t1 {
        return (E * t * t / (2.0 * I), E * t / I);
    }
    let (b, c) = (KP / I, KI / I);
    let root = (b * b / 4.0 - c).sqrt();
    let (s1, s2) = (-b / 2.0 + root, -b / 2.0 - root);
    let a = (E / KP) / (s1 - s2);
    let tau = t - t1;
    let z = a * ((s1 * tau).exp() - (s2 * tau).exp());
    let dz = a * (s1 * (s1 * tau).exp() - s2 * (s2 * tau).exp());
    (E * t1 * t1 / (2.0 * I) + TARGET * tau - z, TARGET - dz)
}

#[test]
fn a_saturated_pi_holds_its_integral_until_its_torque_is_back_inside() {
    let scene = common::scene("tests/data/flywheel_pi.yaml");
    let mut p = Predictor::from_scene(&scene).unwrap();
    let mut cmd = Command::default();
    cmd.joint_velocity.insert("spin".into(), TARGET);
    let cmds = [(0.0, cmd)];
    let traj = p
        .predict(&PredictionRequest::new(&scene.q0, &scene.v0).commands(&cmds))
        .unwrap();
    assert_eq!(traj.samples.len(), 51);
    let (mut dq, mut dw, mut peak) = (0.0f64, 0.0f64, 0.0f64);
    for s in &traj.samples {
        let (q, w) = closed_form(s.t);
        dq = dq.max((s.q[0] - q).abs());
        dw = dw.max((s.v[0] - w).abs());
        peak = peak.max(s.v[0]);
        assert!(
            s.actuator_torque[0].abs() <= E + 1e-12,
            "{}",
            s.actuator_torque[0]
        );
    }
    let t1 = (TARGET - E / KP) * I / E;
    let windup = TARGET * t1 - E * t1 * t1 / (2.0 * I);
    println!(
        "flywheel PI from rest to {TARGET} rad/s: saturated until {t1:.6} s; largest gap to the \
         closed form {dq:.2e} rad, {dw:.2e} rad/s; peak {peak:.6} rad/s (an integral that kept \
         integrating would have held {windup:.4} rad at {t1:.6} s instead of 0)"
    );
    // Measured 5.2e-14 rad and 2.1e-12 rad/s: RK4 at 0.1 ms, the span cut where the torque
    // comes back inside (predicted exactly here: q̈ is constant while saturated).
    assert!(dq < 1e-12 && dw < 1e-10, "{dq:e} rad, {dw:e} rad/s");
}

/// A PI started with the integral its measured effort implies, against the closed form: the
/// flywheel spins at the target ω* while its motor gives τ_m (a load just taken off), so
/// `integrals_from_efforts` gives z₀ = (τ_m − kp·0)/ki. With no load, I ė = −(kp e + ki z),
/// ż = e, z(0) = z₀, e(0) = 0: z = z₀ (s₁ e^{s₂t} − s₂ e^{s₁t}) / (s₁ − s₂) and
/// ω = ω* − ż = ω* − z₀ s₁ s₂ (e^{s₂t} − e^{s₁t}) / (s₁ − s₂): the released motor first
/// speeds the wheel up. Started at zero instead, the wheel would stay at ω*.
#[test]
fn a_pi_starts_from_the_integral_its_measured_effort_implies() {
    let scene = common::scene("tests/data/flywheel_pi.yaml");
    let mut p = Predictor::from_scene(&scene).unwrap();
    let mut cmd = Command::default();
    cmd.joint_velocity.insert("spin".into(), TARGET);
    let tau_m = 0.6; // [N·m], inside the effort E
    let v = [TARGET];
    let mut z = [f64::NAN];
    (p.config().actuators()).integrals_from_efforts(&cmd, &v, &[tau_m], &mut z);
    assert_eq!(z[0], tau_m / KI);
    let cmds = [(0.0, cmd)];
    let traj = p
        .predict(
            &PredictionRequest::new(&scene.q0, &v)
                .commands(&cmds)
                .controller_integrals(&z),
        )
        .unwrap();
    let (b, c) = (KP / I, KI / I);
    let root = (b * b / 4.0 - c).sqrt();
    let (s1, s2) = (-b / 2.0 + root, -b / 2.0 - root);
    let z0 = tau_m / KI;
    let omega = |t: f64| TARGET - z0 * s1 * s2 * ((s2 * t).exp() - (s1 * t).exp()) / (s1 - s2);
    let mut dw = 0.0f64;
    for s in &traj.samples {
        dw = dw.max((s.v[0] - omega(s.t)).abs());
    }
    let t0 = &traj.samples[0];
    println!(
        "flywheel PI at {TARGET} rad/s started from its measured effort {tau_m} N·m: first \
         torque {:.15} N·m, largest gap to the closed form {dw:.2e} rad/s; ω peaks at {:.6} rad/s",
        t0.actuator_torque[0],
        traj.samples.iter().map(|s| s.v[0]).fold(f64::MIN, f64::max)
    );
    assert!((t0.actuator_torque[0] - tau_m).abs() < 1e-14);
    // Measured 1.4e-12 rad/s: RK4 at 0.1 ms on a smooth response.
    assert!(dw < 1e-11, "{dw:e} rad/s");
}
