//! ROS2, the two-stage linearly implicit W-method of Verwer, Spee, Blom and Hundsdorfer (SIAM J.
//! Sci. Comput. 20, 1999), with γ = 1 − 1/√2 (the other L-stable root, 1 + 1/√2, has a 34× larger
//! error constant), on the configuration Lie group:
//!
//! `W = I − γ dt F`, `W k₁ = f(x_n) + γ dt f_t`, `W k₂ = f(x_n ⊕ dt k₁) − 2 k₁ − γ dt f_t`,
//! `x_{n+1} = x_n ⊕ dt (3/2 k₁ + 1/2 k₂)`, with f_t = ∂f/∂t at the span's start (time taken as a
//! state of the method: the continuous controllers' integrals ramp with t).
//!
//! Why this method for the controlled scenes: it is L-stable, so a robot arm held by stiff PD
//! controllers (modes near 10³ /s) does not limit the step; it has order 2 for *any* matrix F
//! (a W-method), so the Lie group's curvature term, the time dependence of the controllers' ramp
//! and an F kept over several steps cost no order; and it takes two evaluations and one factor a
//! step, with no Newton iteration to fail. F = [[0, 1], [∂q̈/∂q, ∂q̈/∂v]] at the step's start
//! (analytic derivatives of the constrained dynamics where the right-hand side has them).

use crate::error::Result;
use crate::model::Model;
use crate::predict::integrators::{
    Accel, StepWorkspace, derivative, factor_shifted, stage, state_jacobian,
};

/// γ of ROS2 (L-stable choice).
pub(in crate::predict) const GAMMA: f64 = 1.0 - std::f64::consts::FRAC_1_SQRT_2;

/// One ROS2 step of `dt` from (q, v) at t, in place. F is evaluated at this step's start when
/// `ws.jac_valid` is false (the caller decides how long one F serves), and W refactored when
/// dt changes.
pub fn ros2_step<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    dt: f64,
    q: &mut [f64],
    v: &mut [f64],
    ws: &mut StepWorkspace,
) -> Result<()> {
    let nv = v.len();
    let n = 2 * nv;
    f.accel(t, q, v, &mut ws.a0)?;
    if !ws.jac_valid {
        state_jacobian(f, model, t, q, v, ws)?;
        factor_shifted(ws, dt * GAMMA, "ROS2")?;
        ws.newton_dt = dt;
    } else if !((dt - ws.newton_dt).abs() <= 1e-12 * dt) {
        // Spans cut from the same sample period give steps equal to rounding; W with either
        // is I − γ dt F with F scaled by 1 ± 1e-12, which a W-method allows (any F keeps its
        // order), so only a real change of dt, or a re-formed F (NaN), refactors.
        factor_shifted(ws, dt * GAMMA, "ROS2")?;
        ws.newton_dt = dt;
    }
    // k₁ = W⁻¹ (f(x_n) + γ dt ∂f/∂t): time as a state of the W-method, so that a motion the
    // controllers hold steady (their integral ramps with t) is a fixed point of the step.
    let gdt = GAMMA * dt;
    ws.ks[0][..nv].copy_from_slice(v);
    for i in 0..nv {
        ws.ks[0][nv + i] = ws.a0[i] + gdt * ws.scratch.dqdd_dt[i];
    }
    ws.newton.solve(&mut ws.ks[0]);
    // k₂ = W⁻¹ (f(x_n ⊕ dt k₁) − 2 k₁ − γ dt ∂f/∂t)
    for i in 0..n {
        ws.dx[i] = dt * ws.ks[0][i];
    }
    stage(model, q, v, &ws.dx, &mut ws.qs, &mut ws.vs);
    derivative(f, model, t + dt, &ws.dx[..nv], &ws.qs, &ws.vs, &mut ws.err)?;
    let (k1, k2) = ws.ks.split_at_mut(1);
    for i in 0..n {
        k2[0][i] = ws.err[i] - 2.0 * k1[0][i];
    }
    for i in 0..nv {
        k2[0][nv + i] -= gdt * ws.scratch.dqdd_dt[i];
    }
    ws.newton.solve(&mut k2[0]);
    for i in 0..n {
        ws.dx[i] = dt * (1.5 * k1[0][i] + 0.5 * k2[0][i]);
    }
    ws.save(q, v);
    stage(model, &ws.q0, &ws.v0, &ws.dx, q, v);
    Ok(())
}

/// The two-stage W-method.
pub struct Ros2;

impl super::Integrator for Ros2 {
    fn method(&self) -> super::Method {
        super::Method::Ros2
    }
    fn order(&self) -> u32 {
        2
    }
    /// Two evaluations and one Jacobian (about two more: docs/performance.md) a step.
    fn evaluations_per_step(&self) -> Option<f64> {
        Some(2.0)
    }
    fn is_adaptive(&self) -> bool {
        false
    }
    fn is_implicit(&self) -> bool {
        true
    }
    fn stability_limit(&self) -> Option<f64> {
        None
    }
    fn linearized_as(&self) -> Option<super::Method> {
        Some(super::Method::Ros2)
    }
}
