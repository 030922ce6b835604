//! The explicit methods: semi-implicit Euler, and Runge–Kutta by Butcher tableau (tableaus.rs)
//! — RK4, and the embedded pairs Dormand–Prince 5(4) and 8(5,3) with their error norms and their
//! step-size control.

use super::radau::RadauWorkspace;
use super::tableaus::{DOP853, DOPRI5, ErrorWeights, RK4, Tableau};
use super::{Accel, Integrator, Method, Step, StepOutcome, StepWorkspace, derivative, stage};
use crate::error::Result;
use crate::model::Model;
use crate::predict::IntegrationSettings;
use crate::predict::covariance::linearize::{self, Linearization};
use crate::system::System;

/// `dx = dt Σ_j w_j k_j`.
fn combine(dx: &mut [f64], ks: &[Vec<f64>], w: &[f64], dt: f64) {
    dx.iter_mut().for_each(|x| *x = 0.0);
    for (k, &a) in ks.iter().zip(w) {
        if a != 0.0 {
            for (d, kk) in dx.iter_mut().zip(k) {
                *d += dt * a * kk;
            }
        }
    }
}

/// One explicit RK step in place; with an embedded pair the error vector lands in `ws.err`.
#[allow(clippy::too_many_arguments)]
pub fn explicit_step<F: Accel>(
    f: &mut F,
    model: &Model,
    tab: &Tableau,
    t: f64,
    dt: f64,
    q: &mut [f64],
    v: &mut [f64],
    ws: &mut StepWorkspace,
) -> Result<()> {
    let s = tab.b.len();
    // A retried step (rejected, state restored) keeps its first stage, f(t, q_n, v_n).
    let reuse = ws.first_stage_at.take() == Some(t) && q == &ws.q0[..] && v == &ws.v0[..];
    for i in 0..s {
        if i == 0 && reuse && tab.c[0] == 0.0 {
            continue;
        }
        let (done, rest) = ws.ks.split_at_mut(i);
        combine(&mut ws.dx, done, tab.a[i], dt);
        stage(model, q, v, &ws.dx, &mut ws.qs, &mut ws.vs);
        derivative(
            f,
            model,
            t + tab.c[i] * dt,
            &ws.dx[..v.len()],
            &ws.qs,
            &ws.vs,
            &mut rest[0],
        )?;
    }
    match tab.error {
        ErrorWeights::None => {}
        ErrorWeights::Embedded(bh) => {
            ws.err.iter_mut().for_each(|x| *x = 0.0);
            for (k, (&b, &b2)) in ws.ks.iter().zip(tab.b.iter().zip(bh)) {
                for (e, kk) in ws.err.iter_mut().zip(k) {
                    *e += dt * (b - b2) * kk;
                }
            }
        }
        ErrorWeights::Dop853 { e5, e3 } => {
            combine(&mut ws.err, &ws.ks[..s], e5, dt);
            combine(&mut ws.err3, &ws.ks[..s], e3, dt);
        }
    }
    combine(&mut ws.dx, &ws.ks[..s], tab.b, dt);
    ws.save(q, v);
    stage(model, &ws.q0, &ws.v0, &ws.dx, q, v);
    Ok(())
}

/// Semi-implicit Euler step in place: v⁺ = v + dt q̈(q, v), q⁺ = q ⊕ dt v⁺.
pub fn semi_implicit_euler_step<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    dt: f64,
    q: &mut [f64],
    v: &mut [f64],
    ws: &mut StepWorkspace,
) -> Result<()> {
    f.accel(t, q, v, &mut ws.a0)?;
    for i in 0..v.len() {
        v[i] += dt * ws.a0[i];
    }
    ws.q0.copy_from_slice(q);
    model.integrate(&ws.q0, v, dt, q);
    Ok(())
}

/// RMS of the DOPRI5 error scaled by atol + rtol·|x| (1 for configuration rows, |v| for velocity).
fn dopri5_error_norm(step: &StepWorkspace, v: &[f64], s: &IntegrationSettings) -> f64 {
    let nv = v.len();
    let (v_old, e) = (step.saved_v(), &step.err);
    let sum: f64 = e
        .iter()
        .enumerate()
        .map(|(i, ei)| {
            let x = if i < nv {
                1.0
            } else {
                v_old[i - nv].abs().max(v[i - nv].abs())
            };
            (ei / (s.atol + s.rtol * x)).powi(2)
        })
        .sum();
    (sum / e.len().max(1) as f64).sqrt()
}

/// DOP853's error norm (Hairer's dop853.f): with e5, e3 the RMS-free sums of (err/scale)² of the
/// 5th- and 3rd-order estimates, `e5 / √((e5 + 0.01 e3) · n)`: the 5th-order estimate, damped
/// where the two disagree; scale as DOPRI5's.
fn dop853_error_norm(step: &StepWorkspace, v: &[f64], s: &IntegrationSettings) -> f64 {
    let nv = v.len();
    let v_old = step.saved_v();
    let (mut e5, mut e3) = (0.0, 0.0);
    for i in 0..2 * nv {
        let x = if i < nv {
            1.0
        } else {
            v_old[i - nv].abs().max(v[i - nv].abs())
        };
        let sc = s.atol + s.rtol * x;
        e5 += (step.err[i] / sc).powi(2);
        e3 += (step.err3[i] / sc).powi(2);
    }
    if e5 == 0.0 && e3 == 0.0 {
        return 0.0;
    }
    e5 / ((e5 + 0.01 * e3) * (2 * nv) as f64).sqrt()
}

/// An embedded explicit pair: its tableau, its error norm and its step-size controller's
/// constants, for [`embedded_step`].
trait EmbeddedPair {
    const TABLEAU: &'static Tableau;
    /// The smallest error norm the controller takes (a vanishing estimate grows the step by
    /// `MAX_GROWTH`, not without bound).
    const NORM_FLOOR: f64;
    /// The controller's exponent, −1/(q + 1) for an error estimate of order q.
    const EXPONENT: f64;
    /// The most an accepted step lets the next one grow.
    const MAX_GROWTH: f64;
    /// The step accepted right after a rejection does not grow the next one.
    const HOLD_AFTER_REJECTION: bool;
    /// The error norm of the last step (1: at the tolerance).
    fn error_norm(step: &StepWorkspace, v: &[f64], s: &IntegrationSettings) -> f64;
}

/// One step of an embedded pair and its step-size control: the next step is
/// dt · clamp(0.9 norm^EXPONENT, 0.2, MAX_GROWTH) (at most dt right after a rejection where the
/// pair holds it); a step over the tolerance (or with a non-finite norm) is undone and retried
/// at most half as long.
fn embedded_step<P: EmbeddedPair, F: Accel>(
    f: &mut F,
    model: &Model,
    (t, dt): (f64, f64),
    q: &mut [f64],
    v: &mut [f64],
    ws: &mut StepWorkspace,
    s: &IntegrationSettings,
) -> Result<Option<StepOutcome>> {
    explicit_step(f, model, P::TABLEAU, t, dt, q, v, ws)?;
    let norm = P::error_norm(ws, v, s);
    let factor = (0.9 * norm.max(P::NORM_FLOOR).powf(P::EXPONENT)).clamp(0.2, P::MAX_GROWTH);
    Ok(Some(if norm > 1.0 || !norm.is_finite() {
        ws.restore(q, v);
        // The retry starts from the same state: its first stage is the one just evaluated.
        ws.first_stage_at = Some(t);
        ws.after_rejection = true;
        StepOutcome {
            accepted: false,
            h_next: dt * factor.min(0.5),
        }
    } else {
        // Hairer's rule (dop853.f): the step accepted right after a rejection does not let
        // the next one grow; the estimate that just failed says the error is rising.
        let factor = if ws.after_rejection && P::HOLD_AFTER_REJECTION {
            factor.min(1.0)
        } else {
            factor
        };
        ws.after_rejection = false;
        StepOutcome {
            accepted: true,
            h_next: dt * factor,
        }
    }))
}

impl EmbeddedPair for Dopri5 {
    const TABLEAU: &'static Tableau = &DOPRI5;
    const NORM_FLOOR: f64 = 1e-10;
    const EXPONENT: f64 = -0.2;
    const MAX_GROWTH: f64 = 5.0;
    // Held, the stiff chain's stability-bound steps (tests/it/radau.rs) lost accuracy.
    const HOLD_AFTER_REJECTION: bool = false;
    fn error_norm(step: &StepWorkspace, v: &[f64], s: &IntegrationSettings) -> f64 {
        dopri5_error_norm(step, v, s)
    }
}

impl EmbeddedPair for Dop853 {
    const TABLEAU: &'static Tableau = &DOP853;
    const NORM_FLOOR: f64 = 1e-12;
    const EXPONENT: f64 = -1.0 / 8.0;
    const MAX_GROWTH: f64 = 10.0;
    const HOLD_AFTER_REJECTION: bool = true;
    fn error_norm(step: &StepWorkspace, v: &[f64], s: &IntegrationSettings) -> f64 {
        dop853_error_norm(step, v, s)
    }
}

/// Semi-implicit (symplectic) Euler.
pub struct SemiImplicitEuler;
/// Classical Runge–Kutta of order 4.
pub struct Rk4;
/// Dormand–Prince 5(4).
pub struct Dopri5;
/// Dormand–Prince 8(5,3).
pub struct Dop853;

impl Integrator for SemiImplicitEuler {
    fn method(&self) -> Method {
        Method::SemiImplicitEuler
    }
    fn order(&self) -> u32 {
        1
    }
    fn evaluations_per_step(&self) -> Option<f64> {
        Some(1.0)
    }
    fn is_adaptive(&self) -> bool {
        false
    }
    fn is_implicit(&self) -> bool {
        false
    }
    fn stability_limit(&self) -> Option<f64> {
        Some(2.0)
    }
    fn linearized_as(&self) -> Option<Method> {
        Some(Method::SemiImplicitEuler)
    }
}

impl Integrator for Rk4 {
    fn method(&self) -> Method {
        Method::Rk4
    }
    fn order(&self) -> u32 {
        4
    }
    fn evaluations_per_step(&self) -> Option<f64> {
        Some(4.0)
    }
    fn is_adaptive(&self) -> bool {
        false
    }
    fn is_implicit(&self) -> bool {
        false
    }
    fn stability_limit(&self) -> Option<f64> {
        Some(2.8)
    }
    fn linearized_as(&self) -> Option<Method> {
        Some(Method::Rk4)
    }
}

/// The embedded pairs' steps are set by a tolerance on the nominal trajectory; Φ of one
/// covariance chunk needs the 4 stages of RK4 to reach the chunk check's accuracy where DOPRI5
/// spends 6 and DOP853 12, and the check still holds every chunk to the recorded motion.
impl Integrator for Dopri5 {
    fn method(&self) -> Method {
        Method::Dopri5
    }
    fn order(&self) -> u32 {
        5
    }
    fn evaluations_per_step(&self) -> Option<f64> {
        None
    }
    fn is_adaptive(&self) -> bool {
        true
    }
    fn is_implicit(&self) -> bool {
        false
    }
    fn stability_limit(&self) -> Option<f64> {
        None
    }
    fn linearized_as(&self) -> Option<Method> {
        Some(Method::Rk4)
    }
}

impl Integrator for Dop853 {
    fn method(&self) -> Method {
        Method::Dop853
    }
    fn order(&self) -> u32 {
        8
    }
    fn evaluations_per_step(&self) -> Option<f64> {
        None
    }
    fn is_adaptive(&self) -> bool {
        true
    }
    fn is_implicit(&self) -> bool {
        false
    }
    fn stability_limit(&self) -> Option<f64> {
        None
    }
    fn linearized_as(&self) -> Option<Method> {
        Some(Method::Rk4)
    }
}

// Every explicit step linearizes as itself (an embedded pair's as a fixed step); the prediction's
// covariance takes the embedded pairs' steps as RK4's (`linearized_as`).
impl Step for SemiImplicitEuler {
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
        semi_implicit_euler_step(f, model, t, dt, q, v, ws)?;
        Ok(None)
    }

    fn linearize(
        &self,
        sys: &mut System,
        lin: &mut Linearization,
        (q, v): (&[f64], &[f64]),
        tau: &[f64],
        dt: f64,
    ) -> Result<()> {
        linearize::semi_implicit_euler(sys, lin, q, v, tau, dt)
    }
}

impl Step for Rk4 {
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
        explicit_step(f, model, &RK4, t, dt, q, v, ws)?;
        Ok(None)
    }

    fn linearize(
        &self,
        sys: &mut System,
        lin: &mut Linearization,
        (q, v): (&[f64], &[f64]),
        tau: &[f64],
        dt: f64,
    ) -> Result<()> {
        linearize::explicit(sys, lin, &RK4, q, v, tau, dt)
    }
}

/// The embedded pairs' steps: [`embedded_step`] with each pair's constants.
impl<P: EmbeddedPair + Integrator> Step for P {
    fn step<F: Accel>(
        &self,
        f: &mut F,
        model: &Model,
        span: (f64, f64),
        q: &mut [f64],
        v: &mut [f64],
        ws: &mut StepWorkspace,
        _: &mut RadauWorkspace,
        s: &IntegrationSettings,
    ) -> Result<Option<StepOutcome>> {
        embedded_step::<P, F>(f, model, span, q, v, ws, s)
    }

    fn linearize(
        &self,
        sys: &mut System,
        lin: &mut Linearization,
        (q, v): (&[f64], &[f64]),
        tau: &[f64],
        dt: f64,
    ) -> Result<()> {
        linearize::explicit(sys, lin, P::TABLEAU, q, v, tau, dt)
    }
}
