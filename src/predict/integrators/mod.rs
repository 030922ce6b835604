//! One step of each integrator on the configuration Lie group. The state is (q, v): q on the
//! group (nq), v in R^nv. For a stage, `Θ` is the tangent increment from q_n (so `q = q_n ⊕ Θ`),
//! and a stage derivative is `k = (dexp⁻¹_{−Θ}(v), q̈)` ∈ R^{2nv}. Every buffer lives in a
//! [`StepWorkspace`] sized once per model: a step allocates nothing.

// Adding an integrator: its file here (its step in `Step`, what the rest of the prediction
// knows of it in `Integrator`), its `mod` line, and its one entry in `methods!` (methods.rs).
mod explicit;
pub(in crate::predict) mod lie;
mod methods;
pub(in crate::predict) mod radau;
mod radau_tableau;
pub(in crate::predict) mod ros2;
pub(in crate::predict) mod sdirk2;
mod shifted;
pub(in crate::predict) mod tableaus;

use crate::actuators::Actuators;
use crate::algorithm::DENSE_EAGER_NV;
use crate::error::{Error, Result};
use crate::model::Model;
use lie::dexp_inv;
pub(in crate::predict) use methods::Step;
pub use methods::{ErrorEstimator, Integrator, Method, StepOutcome};
use nalgebra::DMatrix;
pub(in crate::predict) use shifted::ShiftedFactor;
pub use tableaus::{MAX_STAGES, Tableau};

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

/// Buffers of a finite-difference Jacobian (nv or 2nv each), and what an analytic one keeps
/// (nv × nv and nv × 2nv: sized at build up to `DENSE_EAGER_NV` coordinates, by the first
/// analytic Jacobian above).
#[derive(Clone, Debug, Default)]
pub struct JacobianScratch {
    dx: Vec<f64>,
    qs: Vec<f64>,
    vs: Vec<f64>,
    ap: Vec<f64>,
    /// ∂q̈/∂t at fixed (q, v) where the last Jacobian was taken (nv): the continuous
    /// controllers' own torque rate through ∂q̈/∂τ (analytic), or a difference in t.
    pub(in crate::predict) dqdd_dt: Vec<f64>,
    /// Where the last analytic Jacobian was taken: ∂q̈/∂τ (nv × nv, column j for τ_j) and
    /// ∂q̈/∂(δq, v) without the continuous controllers' feedback (nv × 2nv, column-major). The
    /// controllers enter F only through their feedback through ∂q̈/∂τ, so a new target (their
    /// ∂q̈/∂t) or a controller that saturates or comes back inside (its feedback leaves or
    /// enters) re-forms F from these without new derivatives
    /// ([`JacobianScratch::apply_controllers`]).
    pub(in crate::predict) dqdd_dtau: Vec<f64>,
    passive: Vec<f64>,
    /// False after a difference Jacobian, which has neither.
    pub(in crate::predict) has_dqdd_dtau: bool,
}

impl JacobianScratch {
    pub fn new(nq: usize, nv: usize) -> Self {
        let dense = if nv <= DENSE_EAGER_NV { nv * nv } else { 0 };
        Self {
            dx: vec![0.0; 2 * nv],
            qs: vec![0.0; nq],
            vs: vec![0.0; nv],
            ap: vec![0.0; nv],
            dqdd_dt: vec![0.0; nv],
            dqdd_dtau: vec![0.0; dense],
            passive: vec![0.0; 2 * dense],
            has_dqdd_dtau: false,
        }
    }

    /// Keep F's lower half `jac` (before the controllers' feedback) and ∂q̈/∂τ.
    pub(in crate::predict) fn keep_passive(&mut self, jac: &DMatrix<f64>, dqdd_dtau: &[f64]) {
        let nv = self.dqdd_dt.len();
        self.dqdd_dtau.resize(nv * nv, 0.0);
        self.passive.resize(2 * nv * nv, 0.0);
        for c in 0..2 * nv {
            for r in 0..nv {
                self.passive[c * nv + r] = jac[(nv + r, c)];
            }
        }
        self.dqdd_dtau.copy_from_slice(dqdd_dtau);
        self.has_dqdd_dtau = true;
    }

    /// F's lower half ← the kept one plus each unsaturated continuous controller's feedback at
    /// (t, q, v) (a joint torque −k q − d v moves q̈ by ∂q̈/∂τ_j (−k, −d) on its joint's
    /// columns; 1-DOF: its tangent column is its v index), and ∂q̈/∂t from their rates. False
    /// (F untouched) after a difference Jacobian.
    pub(in crate::predict) fn apply_controllers(
        &mut self,
        control: &Actuators,
        (t, q, v): (f64, &[f64], &[f64]),
        jac: &mut DMatrix<f64>,
    ) -> bool {
        if !self.has_dqdd_dtau {
            return false;
        }
        let nv = self.dqdd_dt.len();
        let n = 2 * nv;
        let f = jac.as_mut_slice();
        for (col, kept) in f.chunks_exact_mut(n).zip(self.passive.chunks_exact(nv)) {
            col[nv..].copy_from_slice(kept);
        }
        let dtau = &self.dqdd_dtau;
        control.continuous_feedback(t, q, v, |fb| {
            let column = &dtau[fb.iv * nv..(fb.iv + 1) * nv];
            let (dq, dv) = (fb.iv * n + nv, (nv + fb.iv) * n + nv);
            for (r, g) in column.iter().enumerate() {
                f[dq + r] -= g * fb.k;
                f[dv + r] -= g * fb.d;
            }
        });
        self.retarget(control, (t, q, v));
        true
    }

    /// ∂q̈/∂t = Σ_j ∂q̈/∂τ_j · rate_j: the continuous controllers' torque rates (a PI's ki ×
    /// target) at (t, q, v) through the kept ∂q̈/∂τ. Left as it is after a difference
    /// Jacobian, which carries no ∂q̈/∂t.
    pub(in crate::predict) fn retarget(
        &mut self,
        control: &Actuators,
        (t, q, v): (f64, &[f64], &[f64]),
    ) {
        if !self.has_dqdd_dtau {
            return;
        }
        let nv = self.dqdd_dt.len();
        let (dt, dtau) = (&mut self.dqdd_dt, &self.dqdd_dtau);
        dt.iter_mut().for_each(|x| *x = 0.0);
        control.continuous_feedback(t, q, v, |fb| {
            let column = &dtau[fb.iv * nv..(fb.iv + 1) * nv];
            for (d, g) in dt.iter_mut().zip(column) {
                *d += g * fb.rate;
            }
        });
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
    // No ∂q̈/∂t here (a W-method keeps its order without it).
    s.dqdd_dt.iter_mut().for_each(|x| *x = 0.0);
    s.has_dqdd_dtau = false;
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

/// Buffers of one step, sized for a model (nq, nv) and reused by every step. The implicit
/// methods' F and W (2nv × 2nv and 2 nv²) are sized at build up to `DENSE_EAGER_NV`
/// coordinates, by the first step that forms them above: an explicit step of a large tree holds
/// O(nv).
#[derive(Clone, Debug, Default)]
pub struct StepWorkspace {
    /// Stage derivatives k_i (2nv each), up to 12 stages (DOP853).
    pub(in crate::predict) ks: Vec<Vec<f64>>,
    pub(in crate::predict) qs: Vec<f64>,
    pub(in crate::predict) vs: Vec<f64>,
    pub(in crate::predict) dx: Vec<f64>,
    pub(in crate::predict) q0: Vec<f64>,
    pub(in crate::predict) v0: Vec<f64>,
    /// Embedded error vector (Θ, Δv) of the last DOPRI5 step, DOP853's 5th-order one (2nv).
    pub err: Vec<f64>,
    /// DOP853's 3rd-order error vector (2nv).
    pub err3: Vec<f64>,
    /// SDIRK2 and ROS2: F = ∂k/∂(Θ, v) (analytic, or finite differences), the factored
    /// I − dt γ F, the residual. `jac` is kept across steps while Newton converges
    /// (`jac_valid`); `newton` is refactored from it when dt moves (`newton_dt`).
    pub(in crate::predict) jac: DMatrix<f64>,
    pub(in crate::predict) newton: ShiftedFactor,
    pub(in crate::predict) resid: Vec<f64>,
    pub(in crate::predict) a0: Vec<f64>,
    pub(in crate::predict) scratch: JacobianScratch,
    /// dt of the factor in `newton`.
    pub(in crate::predict) newton_dt: f64,
    /// `jac` may be used (false: recompute it at the next step).
    pub(in crate::predict) jac_valid: bool,
    /// `jac` was computed at this step's start state (a Newton failure is then final).
    pub(in crate::predict) jac_fresh: bool,
    /// Jacobians computed since the lane started.
    pub(in crate::predict) jacobians: usize,
    /// Versions of `jac`: each Jacobian computed and each re-formed (`reform`).
    pub(in crate::predict) forms: usize,
    /// `ks[0]` is the derivative at the saved state (`q0`, `v0`) at this time [s]: a step
    /// retried after a rejection starts from it without evaluating it again.
    pub(in crate::predict) first_stage_at: Option<f64>,
    /// The last step of an embedded pair was rejected: the next accepted one does not grow
    /// the step after it.
    pub(in crate::predict) after_rejection: bool,
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
            jac: if nv <= DENSE_EAGER_NV {
                DMatrix::zeros(n, n)
            } else {
                DMatrix::zeros(0, 0)
            },
            newton: ShiftedFactor::new(nv),
            resid: vec![0.0; n],
            a0: vec![0.0; nv],
            scratch: JacobianScratch::new(nq, nv),
            newton_dt: f64::NAN,
            jac_valid: false,
            jac_fresh: false,
            jacobians: 0,
            forms: 0,
            first_stage_at: None,
            after_rejection: false,
        }
    }

    /// Re-form the valid F at (t, q, v) for the continuous controllers' current feedback
    /// ([`JacobianScratch::apply_controllers`]), W refactored at the next step. False where it
    /// cannot (no F, or a difference one): the caller takes a fresh F.
    pub(in crate::predict) fn reform(
        &mut self,
        control: &Actuators,
        state: (f64, &[f64], &[f64]),
    ) -> bool {
        if !self.jac_valid
            || !self
                .scratch
                .apply_controllers(control, state, &mut self.jac)
        {
            return false;
        }
        self.newton_dt = f64::NAN;
        self.forms += 1;
        true
    }

    /// Forget the SDIRK2 Jacobian (a new run, or the state jumped).
    pub fn invalidate(&mut self) {
        self.jac_valid = false;
        self.newton_dt = f64::NAN;
        self.first_stage_at = None;
        self.after_rejection = false;
    }

    /// Step with `other`'s F from now on (refactored at the next step): a W-method keeps its
    /// order with any F, and the error estimate's companion takes the answer's, computed at
    /// nearly the same state, instead of its own.
    pub(in crate::predict) fn share_jacobian(&mut self, other: &StepWorkspace) {
        size_square(&mut self.jac, other.jac.nrows());
        self.jac.copy_from(&other.jac);
        // `Vec::clone_from` reuses the allocation where the sizes agree (every step after the
        // first).
        (self.scratch.dqdd_dt).clone_from(&other.scratch.dqdd_dt);
        (self.scratch.dqdd_dtau).clone_from(&other.scratch.dqdd_dtau);
        (self.scratch.passive).clone_from(&other.scratch.passive);
        self.scratch.has_dqdd_dtau = other.scratch.has_dqdd_dtau;
        self.jac_valid = true;
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

/// ∂k/∂(Θ, v) at (q_n, v_n) into `ws.jac` (`ws.a0` = q̈(q_n, v_n)): [[0, 1], [∂q̈/∂q, ∂q̈/∂v]],
/// analytic where the right-hand side has derivatives. The curvature of the group (∂dexp⁻¹/∂Θ,
/// zero at Θ = 0) is left out: the methods that use it iterate (SDIRK2) or need no exact F (ROS2).
pub(in crate::predict) fn state_jacobian<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    q: &[f64],
    v: &[f64],
    ws: &mut StepWorkspace,
) -> Result<()> {
    let nv = v.len();
    size_square(&mut ws.jac, 2 * nv);
    ws.jac.as_mut_slice().fill(0.0);
    for i in 0..nv {
        ws.jac[(i, nv + i)] = 1.0; // ∂(stage velocity)/∂v
    }
    f.accel_jacobian(model, (t, q, v), &ws.a0, &mut ws.jac, &mut ws.scratch)?;
    ws.jac_fresh = true;
    ws.jac_valid = true;
    ws.jacobians += 1;
    ws.forms += 1;
    Ok(())
}

/// `m` sized n × n, when it is not (its entries then zero).
fn size_square(m: &mut DMatrix<f64>, n: usize) {
    if m.nrows() != n || m.ncols() != n {
        *m = DMatrix::zeros(n, n);
    }
}

/// `ws.newton` ← the factored I − dtg · `ws.jac`; `method` names the step in the error.
pub(in crate::predict) fn factor_shifted(
    ws: &mut StepWorkspace,
    dtg: f64,
    method: &str,
) -> Result<()> {
    if !ws.newton.factor(&ws.jac, dtg) {
        return Err(Error::StepTooLarge {
            message: format!("the {method} matrix I − γ dt F is singular"),
        });
    }
    Ok(())
}

/// Stage state from the increment `dx = (Θ, Δv)`: q = q_n ⊕ Θ, v = v_n + Δv.
pub(in crate::predict) fn stage(
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
pub(in crate::predict) fn derivative<F: Accel>(
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
