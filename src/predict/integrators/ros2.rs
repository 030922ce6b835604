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
use crate::predict::IntegrationSettings;
use crate::predict::covariance::linearize::{self, Linearization};
use crate::predict::integrators::radau::RadauWorkspace;
use crate::predict::integrators::tableaus::ROS2_GAMMA as GAMMA;
use crate::predict::integrators::{
    Accel, StepOutcome, StepWorkspace, derivative, factor_shifted, stage, state_jacobian,
};

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
    } else if ws.newton_dt.is_nan() || (dt - ws.newton_dt).abs() > 1e-12 * dt {
        // Spans cut from the same sample period give steps equal to rounding; W with either
        // is I − γ dt F with F scaled by 1 ± 1e-12, which a W-method allows (any F keeps its
        // order), so only a real change of dt, or a re-formed F (NaN), refactors.
        factor_shifted(ws, dt * GAMMA, "ROS2")?;
        ws.newton_dt = dt;
    }
    // Slices of known length up front: the loops below then run without bounds checks.
    let StepWorkspace {
        ks,
        a0,
        scratch,
        newton,
        dx,
        qs,
        vs,
        err,
        q0,
        v0,
        ..
    } = ws;
    let (ft, a0, dx, err) = (
        &scratch.dqdd_dt[..nv],
        &a0[..nv],
        &mut dx[..n],
        &mut err[..n],
    );
    let (k1, rest) = ks.split_at_mut(1);
    let (k1, k2) = (&mut k1[0][..n], &mut rest[0][..n]);
    // k₁ = W⁻¹ (f(x_n) + γ dt ∂f/∂t): time as a state of the W-method, so that a motion the
    // controllers hold steady (their integral ramps with t) is a fixed point of the step.
    let gdt = GAMMA * dt;
    k1[..nv].copy_from_slice(v);
    for ((k, &a), &f) in k1[nv..].iter_mut().zip(a0).zip(ft) {
        *k = a + gdt * f;
    }
    newton.solve(k1);
    // k₂ = W⁻¹ (f(x_n ⊕ dt k₁) − 2 k₁ − γ dt ∂f/∂t)
    for (d, &k) in dx.iter_mut().zip(k1.iter()) {
        *d = dt * k;
    }
    stage(model, q, v, dx, qs, vs);
    derivative(f, model, t + dt, &dx[..nv], qs, vs, err)?;
    for ((k, &e), &k1) in k2.iter_mut().zip(err.iter()).zip(k1.iter()) {
        *k = e - 2.0 * k1;
    }
    for (k, &f) in k2[nv..].iter_mut().zip(ft) {
        *k -= gdt * f;
    }
    newton.solve(k2);
    for ((d, &k1), &k2) in dx.iter_mut().zip(k1.iter()).zip(k2.iter()) {
        *d = dt * (1.5 * k1 + 0.5 * k2);
    }
    q0.copy_from_slice(q);
    v0.copy_from_slice(v);
    stage(model, q0, v0, dx, q, v);
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
    fn is_w_method(&self) -> bool {
        true
    }
}

impl super::Step for Ros2 {
    fn step<F: Accel>(
        &self,
        f: &mut F,
        model: &Model,
        (t, dt): (f64, f64),
        q: &mut [f64],
        v: &mut [f64],
        ws: &mut StepWorkspace,
        _: &mut RadauWorkspace,
        _: &IntegrationSettings,
    ) -> Result<Option<StepOutcome>> {
        ros2_step(f, model, t, dt, q, v, ws)?;
        Ok(None)
    }

    fn linearize(
        &self,
        sys: &mut crate::system::System,
        lin: &mut Linearization,
        (q, v): (&[f64], &[f64]),
        tau: &[f64],
        dt: f64,
    ) -> Result<()> {
        linearize::ros2::ros2(sys, lin, q, v, tau, dt)
    }
}
