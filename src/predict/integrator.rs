//! One step of each integrator on the configuration Lie group. The state is (q, v): q on the
//! group (nq), v in R^nv. For a stage, `Θ` is the tangent increment from q_n (so `q = q_n ⊕ Θ`),
//! and a stage derivative is `k = (dexp⁻¹_{−Θ}(v), q̈)` ∈ R^{2nv}. Every buffer lives in a
//! [`StepWorkspace`] sized once per model: a step allocates nothing.

use super::lie::dexp_inv;
pub use super::tableaus::{DOP853, DOPRI5, ErrorWeights, MAX_STAGES, RK4, Tableau};
use crate::error::Result;
use crate::model::Model;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// The integration method a scene or request chooses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Semi-implicit (symplectic) Euler: v⁺ = v + dt q̈(q, v), q⁺ = q ⊕ dt v⁺. Order 1.
    SemiImplicitEuler,
    /// Classical Runge–Kutta, order 4 (Munthe-Kaas on the group).
    #[default]
    Rk4,
    /// Dormand–Prince 5(4), adaptive with rtol/atol and an error estimate.
    Dopri5,
    /// Dormand–Prince 8(5,3), adaptive with rtol/atol: tight tolerances on smooth scenes in
    /// fewer evaluations than DOPRI5.
    Dop853,
    /// Alexander's 2-stage L-stable SDIRK (order 2) with simplified Newton: for stiff scenes.
    Sdirk2,
    /// Radau IIA of order 5 (3 implicit stages, L-stable), adaptive with rtol/atol (radau.rs):
    /// for stiff scenes at any accuracy.
    Radau5,
}

impl Method {
    /// Order of the global error (error ∝ dt^p for fixed steps); DOPRI5's is that of its
    /// propagated solution.
    pub fn order(self) -> u32 {
        match self {
            Method::SemiImplicitEuler => 1,
            Method::Rk4 => 4,
            Method::Dopri5 => 5,
            Method::Dop853 => 8,
            Method::Sdirk2 => 2,
            Method::Radau5 => 5,
        }
    }

    /// The name a scene or the CLI uses.
    pub fn name(self) -> &'static str {
        match self {
            Method::SemiImplicitEuler => "semi_implicit_euler",
            Method::Rk4 => "rk4",
            Method::Dopri5 => "dopri5",
            Method::Dop853 => "dop853",
            Method::Sdirk2 => "sdirk2",
            Method::Radau5 => "radau5",
        }
    }

    /// The step adapts to rtol/atol (`dt` is only the first step).
    pub fn is_adaptive(self) -> bool {
        matches!(self, Method::Dopri5 | Method::Dop853 | Method::Radau5)
    }

    /// Explicit methods' stability limit of dt·|λ| on the imaginary axis (oscillators).
    pub fn explicit_stability_limit(self) -> Option<f64> {
        match self {
            Method::SemiImplicitEuler => Some(2.0),
            Method::Rk4 => Some(2.8),
            Method::Dopri5 | Method::Dop853 | Method::Sdirk2 | Method::Radau5 => None,
        }
    }
}

/// q̈ = f(t, q, v), and its Jacobian for the implicit methods.
pub trait Accel {
    fn accel(&mut self, t: f64, q: &[f64], v: &[f64], qdd: &mut [f64]) -> Result<()>;

    /// ∂q̈/∂(δq, v) at (t, q, v) (δq a right tangent perturbation, q ⊕ δq) into the lower half of
    /// `jac` (2nv × 2nv: rows nv.., columns [δq | δv]); `qdd` is q̈(t, q, v). Returns whether
    /// it was analytic. Default: forward differences, 2nv evaluations.
    fn accel_jacobian(
        &mut self,
        model: &Model,
        (t, q, v): (f64, &[f64], &[f64]),
        qdd: &[f64],
        jac: &mut DMatrix<f64>,
        scratch: &mut JacobianScratch,
    ) -> Result<bool> {
        accel_jacobian_fd(self, model, (t, q, v), qdd, jac, scratch)?;
        Ok(false)
    }
}

/// Buffers of a finite-difference Jacobian (nv or 2nv each).
#[derive(Clone, Debug, Default)]
pub struct JacobianScratch {
    dx: Vec<f64>,
    qs: Vec<f64>,
    vs: Vec<f64>,
    ap: Vec<f64>,
}

impl JacobianScratch {
    pub fn new(nq: usize, nv: usize) -> Self {
        Self {
            dx: vec![0.0; 2 * nv],
            qs: vec![0.0; nq],
            vs: vec![0.0; nv],
            ap: vec![0.0; nv],
        }
    }
}

/// ∂q̈/∂(δq, v) by forward differences (step 1e-7, relative to |v| for velocity columns) into
/// the lower half of `jac`; `qdd` = q̈(t, q, v).
pub fn accel_jacobian_fd<F: Accel + ?Sized>(
    f: &mut F,
    model: &Model,
    (t, q, v): (f64, &[f64], &[f64]),
    qdd: &[f64],
    jac: &mut DMatrix<f64>,
    s: &mut JacobianScratch,
) -> Result<()> {
    let nv = v.len();
    for col in 0..2 * nv {
        s.dx.iter_mut().for_each(|x| *x = 0.0);
        let scale = if col < nv {
            1.0
        } else {
            v[col - nv].abs().max(1.0)
        };
        let eps = 1e-7 * scale;
        s.dx[col] = eps;
        stage(model, q, v, &s.dx, &mut s.qs, &mut s.vs);
        f.accel(t, &s.qs, &s.vs, &mut s.ap)?;
        for r in 0..nv {
            jac[(nv + r, col)] = (s.ap[r] - qdd[r]) / eps;
        }
    }
    Ok(())
}

/// Buffers of one step, sized for a model (nq, nv) and reused by every step.
#[derive(Clone, Debug, Default)]
pub struct StepWorkspace {
    /// Stage derivatives k_i (2nv each), up to 12 stages (DOP853).
    pub(super) ks: Vec<Vec<f64>>,
    pub(super) qs: Vec<f64>,
    pub(super) vs: Vec<f64>,
    pub(super) dx: Vec<f64>,
    pub(super) q0: Vec<f64>,
    pub(super) v0: Vec<f64>,
    /// Embedded error vector (Θ, Δv) of the last DOPRI5 step, DOP853's 5th-order one (2nv).
    pub err: Vec<f64>,
    /// DOP853's 3rd-order error vector (2nv).
    pub err3: Vec<f64>,
    /// SDIRK2: ∂k/∂(Θ, v) (analytic, or finite differences), its LU (I − dt γ ∂k/∂x), pivots, residual.
    /// `jac` is kept across steps while Newton converges (`jac_valid`); `newton` is refactored
    /// from it when dt moves by more than rounding (`newton_dt`).
    pub(super) jac: DMatrix<f64>,
    pub(super) newton: DMatrix<f64>,
    pub(super) piv: Vec<usize>,
    pub(super) resid: Vec<f64>,
    pub(super) a0: Vec<f64>,
    pub(super) scratch: JacobianScratch,
    /// dt of the factor in `newton`.
    pub(super) newton_dt: f64,
    /// `jac` may be used (false: recompute it at the next step).
    pub(super) jac_valid: bool,
    /// `jac` was computed at this step's start state (a Newton failure is then final).
    pub(super) jac_fresh: bool,
}

impl StepWorkspace {
    pub fn new(nq: usize, nv: usize) -> Self {
        let n = 2 * nv;
        Self {
            ks: vec![vec![0.0; n]; MAX_STAGES],
            qs: vec![0.0; nq],
            vs: vec![0.0; nv],
            dx: vec![0.0; n],
            q0: vec![0.0; nq],
            v0: vec![0.0; nv],
            err: vec![0.0; n],
            err3: vec![0.0; n],
            jac: DMatrix::zeros(n, n),
            newton: DMatrix::zeros(n, n),
            piv: vec![0; n],
            resid: vec![0.0; n],
            a0: vec![0.0; nv],
            scratch: JacobianScratch::new(nq, nv),
            newton_dt: f64::NAN,
            jac_valid: false,
            jac_fresh: false,
        }
    }

    /// Forget the SDIRK2 Jacobian (a new run, or the state jumped).
    pub fn invalidate(&mut self) {
        self.jac_valid = false;
        self.newton_dt = f64::NAN;
    }

    /// Save (q, v) to restore a rejected step.
    pub fn save(&mut self, q: &[f64], v: &[f64]) {
        self.q0.copy_from_slice(q);
        self.v0.copy_from_slice(v);
    }

    /// The velocity saved at the start of the last step.
    pub fn saved_v(&self) -> &[f64] {
        &self.v0
    }

    /// Restore the state saved by [`StepWorkspace::save`].
    pub fn restore(&self, q: &mut [f64], v: &mut [f64]) {
        q.copy_from_slice(&self.q0);
        v.copy_from_slice(&self.v0);
    }
}

/// Stage state from the increment `dx = (Θ, Δv)`: q = q_n ⊕ Θ, v = v_n + Δv.
pub(super) fn stage(
    model: &Model,
    q: &[f64],
    v: &[f64],
    dx: &[f64],
    qs: &mut [f64],
    vs: &mut [f64],
) {
    let nv = v.len();
    model.integrate(q, &dx[..nv], 1.0, qs);
    for i in 0..nv {
        vs[i] = v[i] + dx[nv + i];
    }
}

/// Stage derivative k = (dexp⁻¹_{−Θ}(v_s), q̈(q_s, v_s)).
pub(super) fn derivative<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    theta: &[f64],
    qs: &[f64],
    vs: &[f64],
    k: &mut [f64],
) -> Result<()> {
    let nv = vs.len();
    dexp_inv(model, theta, vs, &mut k[..nv]);
    f.accel(t, qs, vs, &mut k[nv..])
}

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
    for i in 0..s {
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
pub(super) fn dopri5_error_norm(
    step: &StepWorkspace,
    v: &[f64],
    s: &super::IntegrationSettings,
) -> f64 {
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
pub(super) fn dop853_error_norm(
    step: &StepWorkspace,
    v: &[f64],
    s: &super::IntegrationSettings,
) -> f64 {
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
