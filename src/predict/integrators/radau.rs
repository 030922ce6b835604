//! Radau IIA of order 5: three implicit stages, stiffly accurate and L-stable, with a variable
//! step chosen from an embedded error estimate — the algorithm of Hairer & Wanner's RADAU5
//! (Solving ODEs II, IV.8), on the configuration Lie group.
//!
//! Stages are increments Z_i = (Θ_i, ΔV_i) from x_n = (q_n, v_n), x_i = (q_n ⊕ Θ_i, v_n + ΔV_i),
//! with `Z = h (A ⊗ I) F(Z)`, `F_i = k(x_i) = (dexp⁻¹_{−Θ_i}(v_i), q̈(x_i))` — the Munthe-Kaas
//! stage map of the explicit methods (integrators/mod.rs). c₃ = 1 and b = A's last row, so
//! x_{n+1} = x₃. Drift projection follows the step like any method's (index reduction to the
//! acceleration rows + projection; docs/propagation.md).
//!
//! Simplified Newton with one Jacobian J = ∂k/∂x = [[0, I], [∂q̈/∂q, ∂q̈/∂v]] at x_n, analytic
//! where the right-hand side has derivatives (`Accel::accel_jacobian`). The Newton matrix
//! `A⁻¹/h ⊗ I − I ⊗ J` is block-diagonalised by A⁻¹ = T Λ T⁻¹ (Λ: the real eigenvalue γ and the
//! pair α ± iβ): one real and one complex system of n = 2nv rows per iteration, each reduced to
//! its nv velocity rows through J's identity block (newton.rs). The error estimate is Hairer's:
//! `(γ/h − J)⁻¹ (f(x_n) + Σ d_i Z_i / h)` (order 3), refined by one more evaluation after a
//! rejection; the step size controller is his (with the predictive Gustafsson variant), and the
//! Jacobian is kept while Newton converges fast (θ ≤ 1e-3) and the factorization while the step
//! changes by less than 20 %.

mod newton;

use super::radau_tableau::RadauCoefficients;
use crate::algorithm::DENSE_EAGER_NV;
use crate::error::{Error, Result};
use crate::model::Model;
use crate::predict::integrators::{
    Accel, JacobianScratch, ShiftedFactor, StepOutcome, StepWorkspace, derivative, stage,
};
use nalgebra::DMatrix;
use newton::{
    factor, jacobian, newton_update, solve_real, stage_derivatives, starting_values, transform_back,
};

/// Newton iterations per step before the step is rejected (RADAU5's NIT).
const MAX_NEWTON: usize = 7;
/// Keep the Jacobian after a step whose Newton contraction rate was at most this (THET).
const KEEP_JACOBIAN: f64 = 1e-3;
/// Safety factor of the step size controller.
const SAFE: f64 = 0.9;

/// Buffers and memory of the Radau IIA integrator (Jacobian, factorizations, the last step's
/// collocation polynomial), sized once per model.
#[derive(Clone, Debug, Default)]
pub struct RadauWorkspace {
    co: RadauCoefficients,
    /// J = ∂k/∂x at the start of the step it was computed at (n × n).
    jac: DMatrix<f64>,
    /// The Newton systems reduced to the velocities (newton.rs `factor`): the real shift's,
    /// and the LU of the complex one's real form (2nv × 2nv) with its pivots.
    e1: ShiftedFactor,
    e2: DMatrix<f64>,
    piv2: Vec<usize>,
    /// J_q r for the complex solve, real and imaginary parts (2nv), and its right-hand side
    /// (2nv).
    jq_r: Vec<f64>,
    y2: Vec<f64>,
    /// Stage increments Z_i, transformed W_i = (T⁻¹ Z)_i, stage derivatives F_i (n each).
    z: [Vec<f64>; 3],
    w: [Vec<f64>; 3],
    f: [Vec<f64>; 3],
    /// Newton right-hand sides: the real block (n) and the complex pair (2n).
    r1: Vec<f64>,
    r2: Vec<f64>,
    /// k(x_n), the error estimate and its scale (n each).
    f0: Vec<f64>,
    err: Vec<f64>,
    scal: Vec<f64>,
    /// Collocation polynomial of the last accepted step (divided differences, n each).
    cont: [Vec<f64>; 3],
    qs: Vec<f64>,
    vs: Vec<f64>,
    scratch: JacobianScratch,
    /// The Jacobian may be used; it was computed at this step's start state.
    jac_valid: bool,
    jac_fresh: bool,
    /// h of the factorizations (NaN: none).
    factor_h: f64,
    /// `cont` holds the last accepted step's polynomial, of step `h_old`.
    have_cont: bool,
    h_old: f64,
    /// Newton's convergence memory (RADAU5's FACCON and THETA).
    faccon: f64,
    theta: f64,
    /// Last accepted step and error (Gustafsson controller); the last step was rejected.
    h_acc: f64,
    err_acc: f64,
    first: bool,
    rejected: bool,
    /// This step's internal (rtol, atol).
    tol: (f64, f64),
    /// Jacobian evaluations since `reset` (analytic or by differences).
    pub jacobians: usize,
}

impl RadauWorkspace {
    pub fn new(nq: usize, nv: usize) -> Self {
        let n = 2 * nv;
        let v3 = || [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let mut ws = Self {
            co: RadauCoefficients::new(),
            e1: ShiftedFactor::new(nv),
            piv2: vec![0; n],
            jq_r: vec![0.0; n],
            y2: vec![0.0; n],
            z: v3(),
            w: v3(),
            f: v3(),
            r1: vec![0.0; n],
            r2: vec![0.0; 2 * n],
            f0: vec![0.0; n],
            err: vec![0.0; n],
            scal: vec![0.0; n],
            cont: v3(),
            qs: vec![0.0; nq],
            vs: vec![0.0; nv],
            scratch: JacobianScratch::new(nq, nv),
            ..Default::default()
        };
        if nv <= DENSE_EAGER_NV {
            ws.size_matrices(n);
        }
        ws.reset();
        ws
    }

    /// Size J and the two factorizations for n = 2 nv states when they are not: a large
    /// model's are sized by its first Radau step (other methods never hold their 8 nv² entries).
    fn size_matrices(&mut self, n: usize) {
        if self.jac.nrows() != n {
            self.jac = DMatrix::zeros(n, n);
            self.e2 = DMatrix::zeros(n, n);
        }
    }

    /// Forget the Jacobian, factorizations and step history (a new run, or the state jumped).
    pub fn reset(&mut self) {
        self.jac_valid = false;
        self.jac_fresh = false;
        self.factor_h = f64::NAN;
        self.have_cont = false;
        self.faccon = 1.0;
        self.theta = 1.0;
        self.first = true;
        self.rejected = false;
        self.jacobians = 0;
    }
}

/// RADAU5's tolerances: the embedded estimate is of order 3 while the answer is of order 5, so
/// the controller is given rtol' = 0.1 rtol^(2/3) (and atol scaled alike), which makes the global
/// error about follow the user's rtol.
fn internal_tolerances(rtol: f64, atol: f64) -> (f64, f64) {
    let r = 0.1 * rtol.powf(2.0 / 3.0);
    (r, r * atol / rtol)
}

/// One Radau IIA step of at most `dt` from (t, q, v) with tolerances (rtol, atol): on acceptance
/// q, v hold x_{n+1}; on rejection they are unchanged. The caller repeats rejected steps with
/// `h_next` and stops when it underflows.
#[allow(clippy::too_many_arguments)]
pub fn radau5_step<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    h: f64,
    q: &mut [f64],
    v: &mut [f64],
    ws: &mut RadauWorkspace,
    (rtol, atol): (f64, f64),
) -> Result<StepOutcome> {
    let nv = v.len();
    let n = 2 * nv;
    ws.size_matrices(n);
    let (rtol, atol) = internal_tolerances(rtol, atol);
    ws.tol = (rtol, atol);
    let fnewt = (10.0 * f64::EPSILON / rtol).max(0.03f64.min(rtol.sqrt()));
    // Scale: atol + rtol·|x|, with 1 for configuration rows (angles and lengths alike).
    for i in 0..n {
        let x = if i < nv { 1.0 } else { v[i - nv].abs() };
        ws.scal[i] = atol + rtol * x;
    }
    let nd = model.nv;
    let start = &mut ws.f0;
    f.accel(t, q, v, &mut start[nd..])?;
    start[..nd].copy_from_slice(v);
    if !ws.jac_valid {
        jacobian(f, model, t, q, v, ws)?;
    }
    if ws.factor_h != h {
        factor(ws, h)?;
    }
    starting_values(ws, h);
    ws.faccon = ws.faccon.max(f64::EPSILON).powf(0.8);
    ws.theta = ws.faccon;
    let (mut dyn_old, mut thq_old) = (0.0, 0.0);
    let mut iterations = 0;
    let converged = loop {
        if iterations >= MAX_NEWTON {
            break false;
        }
        // F_i = k(x_n ⊕ Z_i).
        let finite = stage_derivatives(f, model, t, h, q, v, ws)?;
        if !finite {
            break false;
        }
        let dy = newton_update(ws, h);
        iterations += 1;
        if !dy.is_finite() {
            break false;
        }
        if iterations > 1 {
            let thq = dy / dyn_old;
            ws.theta = if iterations == 2 {
                thq
            } else {
                (thq * thq_old).sqrt()
            };
            thq_old = thq;
            if ws.theta >= 0.99 {
                break false;
            }
            ws.faccon = ws.theta / (1.0 - ws.theta);
            let left = (MAX_NEWTON - 1 - iterations) as i32;
            if ws.faccon * dy * ws.theta.powi(left) / fnewt >= 1.0 {
                // Will not converge within MAX_NEWTON: a shorter step now.
                let q_newt = (ws.faccon * dy * ws.theta.powi(left) / fnewt).clamp(1e-4, 20.0);
                let shrink = 0.8 * q_newt.powf(-1.0 / (4.0 + left as f64));
                return Ok(reject(ws, h * shrink));
            }
        }
        dyn_old = dy.max(f64::EPSILON);
        transform_back(ws);
        if ws.faccon * dy <= fnewt {
            break true;
        }
    };
    if !converged {
        // RADAU5's unexpected rejection: half the step, with a Jacobian at this state.
        if ws.jac_fresh && h < 1e-12 * t.abs().max(1.0) {
            return Err(Error::StepTooLarge {
                message: format!("Radau IIA Newton iteration does not converge at t = {t} s"),
            });
        }
        return Ok(reject(ws, 0.5 * h));
    }
    let err = error_estimate(f, model, t, h, q, v, ws)?;
    // Step size from the estimate (order 4 of the error: exponent 1/4).
    let nit = MAX_NEWTON as f64;
    let fac = SAFE.min(SAFE * (1.0 + 2.0 * nit) / (iterations as f64 + 2.0 * nit));
    let mut quot = (err.powf(0.25) / fac).clamp(1.0 / 8.0, 5.0);
    if !err.is_finite() || err > 1.0 {
        let h_next = if ws.first { 0.1 * h } else { h / quot };
        return Ok(reject(ws, h_next));
    }
    if !ws.first {
        // Gustafsson's predictive controller.
        let gus = (ws.h_acc / h) * (err * err / ws.err_acc).powf(0.25) / SAFE;
        quot = quot.max(gus.clamp(1.0 / 8.0, 5.0));
    }
    ws.h_acc = h;
    ws.err_acc = err.max(1e-2);
    let mut h_next = h / quot;
    if ws.rejected {
        h_next = h_next.min(h);
    }
    ws.first = false;
    ws.rejected = false;
    accept(model, q, v, ws, h);
    // Reuse the Jacobian while Newton contracts fast, the factorization while h barely moves.
    ws.jac_valid = ws.theta <= KEEP_JACOBIAN;
    ws.jac_fresh = false;
    let ratio = h_next / h;
    if ws.jac_valid && (1.0..=1.2).contains(&ratio) {
        h_next = h;
    }
    Ok(StepOutcome {
        accepted: true,
        h_next,
    })
}

/// A rejected step: the next try is `h_next`, with a fresh Jacobian unless this one was.
fn reject(ws: &mut RadauWorkspace, h_next: f64) -> StepOutcome {
    ws.rejected = true;
    if !ws.jac_fresh {
        ws.jac_valid = false;
    }
    StepOutcome {
        accepted: false,
        h_next,
    }
}

/// Hairer's estimate `(γ/h − J)⁻¹ (f₀ + Σ d_i Z_i / h)` as a scaled RMS norm; when it fails at
/// the first step or after a rejection, once more with f₀ replaced by k(x_n + err) (filters the
/// stiff components).
#[allow(clippy::too_many_arguments)]
fn error_estimate<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    h: f64,
    q: &[f64],
    v: &[f64],
    ws: &mut RadauWorkspace,
) -> Result<f64> {
    let nv = v.len();
    let n = 2 * nv;
    let d = ws.co.d;
    for k in 0..n {
        // Σ d_i Z_i / h in r1 (kept), f₀ + it in err.
        ws.r1[k] = (d[0] * ws.z[0][k] + d[1] * ws.z[1][k] + d[2] * ws.z[2][k]) / h;
        ws.err[k] = ws.f0[k] + ws.r1[k];
    }
    solve_err(ws);
    let mut e = scaled_norm(&ws.err, v, &ws.z[2], ws.tol);
    if e >= 1.0 && (ws.first || ws.rejected) {
        stage(model, q, v, &ws.err, &mut ws.qs, &mut ws.vs);
        if ws.qs.iter().chain(&ws.vs).all(|x| x.is_finite()) {
            derivative(f, model, t, &ws.err[..nv], &ws.qs, &ws.vs, &mut ws.f[0])?;
            for k in 0..n {
                ws.err[k] = ws.f[0][k] + ws.r1[k];
            }
            solve_err(ws);
            e = scaled_norm(&ws.err, v, &ws.z[2], ws.tol);
        }
    }
    Ok(e)
}

/// err ← (γ/h − J)⁻¹ err.
fn solve_err(ws: &mut RadauWorkspace) {
    let mut err = std::mem::take(&mut ws.err);
    solve_real(ws, &mut err);
    ws.err = err;
}

/// RMS of err / (atol + rtol max(|x_n|, |x_{n+1}|)) (1 for configuration rows; v_{n+1} =
/// v_n + ΔV₃).
fn scaled_norm(err: &[f64], v: &[f64], z3: &[f64], (rtol, atol): (f64, f64)) -> f64 {
    let nv = v.len();
    let sum: f64 = (0..2 * nv)
        .map(|i| {
            let x = if i < nv {
                1.0
            } else {
                v[i - nv].abs().max((v[i - nv] + z3[i]).abs())
            };
            (err[i] / (atol + rtol * x)).powi(2)
        })
        .sum();
    (sum / (2 * nv) as f64).sqrt()
}

/// x_{n+1} = x_n ⊕ Z₃, and the collocation polynomial for the next step's starting values.
fn accept(model: &Model, q: &mut [f64], v: &mut [f64], ws: &mut RadauWorkspace, h: f64) {
    let n = ws.f0.len();
    let [c1, c2, _] = ws.co.c;
    for k in 0..n {
        let (z1, z2, z3) = (ws.z[0][k], ws.z[1][k], ws.z[2][k]);
        let a1 = (z2 - z3) / (c2 - 1.0);
        let ak = (z1 - z2) / (c1 - c2);
        let a3 = (ak - z1 / c1) / c2;
        let a2 = (ak - a1) / (c1 - 1.0);
        ws.cont[0][k] = a1;
        ws.cont[1][k] = a2;
        ws.cont[2][k] = a2 - a3;
    }
    ws.have_cont = true;
    ws.h_old = h;
    ws.qs.copy_from_slice(q);
    ws.vs.copy_from_slice(v);
    stage(model, &ws.qs, &ws.vs, &ws.z[2], q, v);
}

/// Radau IIA of order 5 with its embedded error estimate.
pub struct Radau5;

impl super::Integrator for Radau5 {
    fn method(&self) -> super::Method {
        super::Method::Radau5
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
        true
    }
    fn stability_limit(&self) -> Option<f64> {
        None
    }
    fn linearized_as(&self) -> Option<super::Method> {
        None
    }
    /// ROS2 is L-stable as Radau IIA is: its Φ damps the stiff modes Radau's steps step over.
    fn covariance_by_substeps(&self) -> bool {
        true
    }
}

impl super::Step for Radau5 {
    fn step<F: Accel>(
        &self,
        f: &mut F,
        model: &Model,
        (t, dt): (f64, f64),
        q: &mut [f64],
        v: &mut [f64],
        _: &mut StepWorkspace,
        radau: &mut RadauWorkspace,
        s: &crate::predict::IntegrationSettings,
    ) -> Result<Option<StepOutcome>> {
        radau5_step(f, model, t, dt, q, v, radau, (s.rtol, s.atol)).map(Some)
    }
}
