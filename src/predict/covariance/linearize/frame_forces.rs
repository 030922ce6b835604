//! The force elements that act at frames — tyres, turning resistances, frame forces, point
//! springs — moved to each stage of a linearized step and differentiated there, as the joint
//! spring-dampers are.
//!
//! The τ a step is linearized under holds them at the step's start. Held, they leave A without
//! the grip that ties a floating base to the floor: a tyre's friction answers a slip velocity at
//! its slip rate (μ N / s₀ per m/s, ~10⁴ /s for the soft floor's wheels) and its normal force
//! a sinking at the floor's stiffness, and without them the propagated covariance of the
//! soft-floor scene missed the prediction's own sensitivity entirely (relative difference 1.0,
//! tests/it/covariance_sensitivity.rs). So each stage takes
//! `τ_stage = τ + Q_f(q_s, v_s) − Q_f(q₀, v₀)` and adds
//! `∂q̈/∂τ · (∂Q_f/∂δq, ∂Q_f/∂v)` to ∂q̈/∂(δq, v), by forward differences of Q_f
//! ([`ForceJacobian`], 2nv + 1 evaluations a stage, and one at the step's start).

use crate::applied::{Differences, ForceJacobian};
use crate::derivatives::DerivativeData;
use crate::forces::ForceElements;
use crate::linalg::gemm_into;
use crate::system::System;
use nalgebra::DMatrix;

/// The elements acting at frames of a scene and the buffers of their derivatives (sized once).
#[derive(Clone, Debug)]
pub(in crate::predict) struct FrameForces {
    elements: ForceElements,
    /// Q_f at the step's start.
    start: Vec<f64>,
    /// ∂Q_f/∂(δq, v) at the stage, and Q_f there.
    jacobian: ForceJacobian,
    /// ∂q̈/∂τ times either derivative (nv × nv).
    product: DMatrix<f64>,
}

impl FrameForces {
    /// For `sys`, the elements of `forces` that act at frames; `None` when it has none.
    pub(in crate::predict) fn new(sys: &System, forces: &ForceElements) -> Option<Self> {
        let nv = sys.model().nv;
        forces.acting_at_frames().map(|elements| Self {
            elements,
            start: vec![0.0; nv],
            jacobian: ForceJacobian::new(sys.model()),
            product: DMatrix::zeros(nv, nv),
        })
    }

    /// Q_f at the start (q₀, v₀) of the step about to be linearized: the share its τ holds.
    pub(super) fn start_step(&mut self, sys: &mut System, q0: &[f64], v0: &[f64]) {
        // The elements acting at frames do not depend on t.
        ForceJacobian::generalized_force(sys, &mut self.elements, (0.0, q0, v0), &mut self.start);
    }

    /// Moves the elements' share of `tau_stage` from the step's start ([`Self::start_step`]) to
    /// the stage (q, v), and, with `derivatives`, takes their derivatives there (module doc).
    /// Leaves the system's kinematics at a nearby state: the caller's dynamics recompute them.
    pub(super) fn stage(
        &mut self,
        sys: &mut System,
        (q, v): (&[f64], &[f64]),
        tau_stage: &mut [f64],
        derivatives: bool,
    ) {
        let j = &mut self.jacobian;
        if derivatives {
            j.differentiate(sys, &mut self.elements, (0.0, q, v), Differences::Forward);
        } else {
            ForceJacobian::generalized_force(sys, &mut self.elements, (0.0, q, v), &mut j.at);
        }
        for ((tau, a), s) in tau_stage.iter_mut().zip(&j.at).zip(&self.start) {
            *tau += a - s;
        }
    }

    /// ∂q̈/∂(δq, v) += ∂q̈/∂τ · ∂Q_f/∂(δq, v) at the last [`Self::stage`] (`dd` holds ∂q̈/∂τ).
    pub(super) fn add_to(&mut self, dd: &mut DerivativeData) {
        let j = &self.jacobian;
        gemm_into(&mut self.product, 1.0, &dd.dqdd_dtau, &j.dq, 0.0);
        dd.dqdd_dq += &self.product;
        gemm_into(&mut self.product, 1.0, &dd.dqdd_dtau, &j.dv, 0.0);
        dd.dqdd_dv += &self.product;
    }
}
