//! The force elements that act at frames — tyres, turning resistances, frame forces — moved to
//! each stage of a linearized step and differentiated there, as the joint spring-dampers are.
//!
//! The τ a step is linearized under holds them at the step's start. Held, they leave A without
//! the grip that ties a floating base to the floor: a tyre's friction answers a slip velocity at
//! its slip rate (μ N / s₀ per m/s, ~10⁴ /s for the soft floor's wheels) and its normal force
//! a sinking at the floor's stiffness, and without them the propagated covariance of the
//! soft-floor scene missed the prediction's own sensitivity entirely (relative difference 1.0,
//! tests/it/covariance_sensitivity.rs). So each stage takes
//! `τ_stage = τ + Q_f(q_s, v_s) − Q_f(q₀, v₀)` and adds
//! `∂q̈/∂τ · (∂Q_f/∂δq, ∂Q_f/∂v)` to ∂q̈/∂(δq, v). The derivatives are forward differences of
//! Q_f (kinematics and the elements only, 2nv + 2 evaluations a stage): the elements have no
//! analytic derivatives, and a covariance needs far less than their ~1e-7 relative error.

use crate::derivatives::DerivativeData;
use crate::forces::ForceElements;
use crate::linalg::gemm_into;
use crate::system::System;
use nalgebra::DMatrix;

/// Step of the forward differences: 1e-7 of a unit δq, of max(|v_i|, 1) for v.
const EPS: f64 = 1e-7;

/// The elements acting at frames of a scene and the buffers of their derivatives (sized once).
#[derive(Clone, Debug)]
pub(in crate::predict) struct FrameForces {
    elements: ForceElements,
    /// Q_f at the step's start, at the stage, and at a perturbed stage (nv).
    start: Vec<f64>,
    at: Vec<f64>,
    moved: Vec<f64>,
    /// The perturbed state: q ⊕ ε e_c (nq), v + ε e_c (nv), ε e_c (nv).
    q: Vec<f64>,
    v: Vec<f64>,
    e: Vec<f64>,
    /// ∂Q_f/∂δq and ∂Q_f/∂v at the stage (nv × nv), and ∂q̈/∂τ times either.
    dq: DMatrix<f64>,
    dv: DMatrix<f64>,
    product: DMatrix<f64>,
}

impl FrameForces {
    /// For `sys`, the elements of `forces` that act at frames; `None` when it has none.
    pub(in crate::predict) fn new(sys: &System, forces: &ForceElements) -> Option<Self> {
        let (nq, nv) = (sys.model().nq, sys.model().nv);
        forces.acting_at_frames().map(|elements| Self {
            elements,
            start: vec![0.0; nv],
            at: vec![0.0; nv],
            moved: vec![0.0; nv],
            q: vec![0.0; nq],
            v: vec![0.0; nv],
            e: vec![0.0; nv],
            dq: DMatrix::zeros(nv, nv),
            dv: DMatrix::zeros(nv, nv),
            product: DMatrix::zeros(nv, nv),
        })
    }

    /// Q_f at (q, v) into `out` (the elements acting at frames do not depend on t).
    fn eval(sys: &mut System, elements: &mut ForceElements, q: &[f64], v: &[f64], out: &mut [f64]) {
        sys.kinematics_at(q, v);
        out.fill(0.0);
        elements.add_forces_at_frames(sys.model(), sys.data(), v, out);
    }

    /// Moves the elements' share of `tau_stage` from the step's start (q₀, v₀) to the stage
    /// (q, v), and, with `derivatives`, takes their derivatives there (module doc). Leaves the
    /// system's kinematics at a nearby state: the caller's dynamics recompute them.
    pub(super) fn stage(
        &mut self,
        sys: &mut System,
        (q0, v0): (&[f64], &[f64]),
        (q, v): (&[f64], &[f64]),
        tau_stage: &mut [f64],
        derivatives: bool,
    ) {
        let Self {
            elements,
            start,
            at,
            moved,
            q: qp,
            v: vp,
            e,
            dq,
            dv,
            ..
        } = self;
        Self::eval(sys, elements, q0, v0, start);
        Self::eval(sys, elements, q, v, at);
        for ((tau, a), s) in tau_stage.iter_mut().zip(at.iter()).zip(start.iter()) {
            *tau += a - s;
        }
        if !derivatives {
            return;
        }
        let nv = v.len();
        for c in 0..nv {
            e.fill(0.0);
            e[c] = EPS;
            sys.model().integrate(q, e, 1.0, qp);
            Self::eval(sys, elements, qp, v, moved);
            for r in 0..nv {
                dq[(r, c)] = (moved[r] - at[r]) / EPS;
            }
        }
        for c in 0..nv {
            let eps = EPS * v[c].abs().max(1.0);
            vp.copy_from_slice(v);
            vp[c] += eps;
            Self::eval(sys, elements, q, vp, moved);
            for r in 0..nv {
                dv[(r, c)] = (moved[r] - at[r]) / eps;
            }
        }
    }

    /// ∂q̈/∂(δq, v) += ∂q̈/∂τ · ∂Q_f/∂(δq, v) at the last [`Self::stage`] (`dd` holds ∂q̈/∂τ).
    pub(super) fn add_to(&mut self, dd: &mut DerivativeData) {
        gemm_into(&mut self.product, 1.0, &dd.dqdd_dtau, &self.dq, 0.0);
        dd.dqdd_dq += &self.product;
        gemm_into(&mut self.product, 1.0, &dd.dqdd_dtau, &self.dv, 0.0);
        dd.dqdd_dv += &self.product;
    }
}
