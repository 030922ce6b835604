//! The right-hand side the integrators step: actuator torques (held, or continuous controllers
//! evaluated at each stage) and force elements → constrained q̈, and its Jacobian F (analytic
//! derivatives of the dynamics, the controllers' feedback through ∂q̈/∂τ).

use crate::actuators::Actuators;
use crate::algorithm::DENSE_EAGER_NV;
use crate::applied::{
    Differences, ForceJacobian, applied_generalized_force,
    applied_generalized_force_after_kinematics,
};
use crate::derivatives::DerivativeData;
use crate::dynamics::{Baumgarte, Formulation, disagree_beyond_rounding};
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::model::Model;
use crate::predict::InvariantDynamics;
use crate::predict::covariance::linearize::{dynamics_derivatives, stage_options};
use crate::predict::drift::DriftProjector;
use crate::predict::integrators::{Accel, JacobianScratch, accel_jacobian_fd};
use crate::system::{DynamicsOptions, System};
use nalgebra::DMatrix;

/// Buffers of the right-hand side's Jacobian: the analytic derivatives of the dynamics and the
/// force elements' generalized force differenced (kinematics only).
#[derive(Clone, Debug, Default)]
pub(in crate::predict) struct JacobianWork {
    /// The dynamics' derivatives (six nv × nv matrices): built with the workspace up to
    /// `DENSE_EAGER_NV` coordinates, by the first analytic Jacobian above (an explicit
    /// prediction of a large tree never holds them).
    pub(in crate::predict) dd: Option<DerivativeData>,
    /// The force elements' ∂Q/∂(δq, v), differenced: built by the first Jacobian of a scene
    /// whose elements depend on the state beyond its joints (n × n: never on a large tree
    /// without such elements).
    pub(in crate::predict) forces: Option<ForceJacobian>,
}

impl JacobianWork {
    pub(in crate::predict) fn new(sys: &System) -> Self {
        let nv = sys.model().nv;
        Self {
            dd: (nv <= DENSE_EAGER_NV)
                .then(|| DerivativeData::new(sys.model(), sys.constraints().nrows)),
            forces: None,
        }
    }
}

/// The right-hand side: actuator torques (held, or continuous controllers evaluated at the
/// stage) + force elements → constrained q̈.
pub(in crate::predict) struct Rhs<'a> {
    pub(in crate::predict) sys: &'a mut System,
    /// The run's Baumgarte gains.
    pub(in crate::predict) gains: Baumgarte,
    pub(in crate::predict) forces: &'a mut ForceElements,
    pub(in crate::predict) tau_act: &'a [f64],
    /// Continuous controllers (`hold: continuous`), evaluated into `tau_ctl` at every stage
    /// instead of `tau_act`.
    pub(in crate::predict) control: Option<&'a Actuators>,
    pub(in crate::predict) tau_ctl: &'a mut [f64],
    pub(in crate::predict) tau: &'a mut [f64],
    pub(in crate::predict) ls: &'a mut DriftProjector,
    pub(in crate::predict) jw: &'a mut JacobianWork,
    pub(in crate::predict) rows: RowsAt<'a>,
    pub(in crate::predict) probe: Probe<'a>,
    /// The dynamics as a constant form, where the scene has one (`PredictorConfig::invariant`).
    pub(in crate::predict) invariant: Option<&'a InvariantDynamics>,
    pub(in crate::predict) evaluations: usize,
    pub(in crate::predict) least_squares: usize,
}

/// Where the system's kinematics and constraint rows were last evaluated by the drift
/// projection, when it left the state there: the next step's first stage, at that same
/// (t, q, v), reuses them (`DynamicsOptions::rows_evaluated`) instead of a second pass.
pub(in crate::predict) struct RowsAt<'a> {
    pub(in crate::predict) t: Option<f64>,
    pub(in crate::predict) q: &'a mut [f64],
    pub(in crate::predict) v: &'a mut [f64],
}

/// A q̈ the run probed at (t, q, v) (`Predictor::probe_accel`), for the first evaluation there.
pub(in crate::predict) struct Probe<'a> {
    pub(in crate::predict) t: &'a mut Option<f64>,
    pub(in crate::predict) q: &'a [f64],
    pub(in crate::predict) v: &'a [f64],
    pub(in crate::predict) qdd: &'a [f64],
}

impl Probe<'_> {
    /// True once, for the probed state (bitwise): its q̈ is copied into `qdd`.
    pub(in crate::predict) fn take(
        &mut self,
        t: f64,
        q: &[f64],
        v: &[f64],
        qdd: &mut [f64],
    ) -> bool {
        let hit = self.t.take() == Some(t) && self.q == q && self.v == v;
        if hit {
            qdd.copy_from_slice(self.qdd);
        }
        hit
    }
}

impl RowsAt<'_> {
    pub(in crate::predict) fn mark(&mut self, t: f64, q: &[f64], v: &[f64]) {
        self.t = Some(t);
        self.q.copy_from_slice(q);
        self.v.copy_from_slice(v);
    }

    /// True once, for the marked state (bitwise the same q and v: anything else evaluates).
    pub(in crate::predict) fn take(&mut self, t: f64, q: &[f64], v: &[f64]) -> bool {
        self.t.take() == Some(t) && *self.q == *q && *self.v == *v
    }
}

impl Rhs<'_> {
    /// τ at (t, q, v) into `tau`.
    pub(in crate::predict) fn apply(&mut self, t: f64, q: &[f64], v: &[f64]) {
        self.apply_with(t, q, v, false);
    }

    /// τ at (t, q, v) into `tau`; `kinematics_current`: the system's kinematics are already
    /// those of (q, v) at q̈ = 0, which the force elements then read without a pass of their own.
    fn apply_with(&mut self, t: f64, q: &[f64], v: &[f64], kinematics_current: bool) {
        let tau_act: &[f64] = match self.control {
            Some(a) => {
                a.continuous_torque(t, q, v, self.tau_ctl);
                self.tau_ctl
            }
            None => self.tau_act,
        };
        let state = (t, q, v);
        if kinematics_current {
            applied_generalized_force_after_kinematics(
                self.sys,
                self.forces,
                state,
                tau_act,
                self.tau,
            );
        } else {
            applied_generalized_force(self.sys, self.forces, state, tau_act, self.tau);
        }
    }

    /// ∂q̈/∂τ · ∂Q/∂(δq, v) of the force elements (central differences of their generalized
    /// force: kinematics only) added to F's lower half.
    fn force_columns_fd(&mut self, (t, q, v): (f64, &[f64], &[f64]), jac: &mut DMatrix<f64>) {
        let nv = v.len();
        let jw = &mut *self.jw;
        let fj = (jw.forces).get_or_insert_with(|| ForceJacobian::new(self.sys.model()));
        fj.differentiate(self.sys, self.forces, (t, q, v), Differences::Central);
        let dd = jw.dd.as_ref().expect("checked above");
        for col in 0..2 * nv {
            let m = if col < nv { &fj.dq } else { &fj.dv };
            let c = col % nv;
            for r in 0..nv {
                jac[(nv + r, col)] += (0..nv)
                    .map(|j| dd.dqdd_dtau[(r, j)] * m[(j, c)])
                    .sum::<f64>();
            }
        }
    }
}

impl Accel for Rhs<'_> {
    fn accel(&mut self, t: f64, q: &[f64], v: &[f64], qdd: &mut [f64]) -> Result<()> {
        if self.probe.take(t, q, v, qdd) {
            return Ok(());
        }
        self.evaluations += 1;
        let mut rows_evaluated = self.rows.take(t, q, v);
        // The form holds without stabilisation gains (a run under `drift: baumgarte` has them).
        if let Some(form) = self.invariant
            && self.gains == Baumgarte::default()
        {
            self.apply(t, q, v);
            form.accel(v, self.tau, qdd);
            return Ok(());
        }
        // Force elements that read placements and twists (a point spring) and the multiplier
        // form's constraint rows need the same kinematics pass at (q, v, q̈ = 0): the rows are
        // evaluated first and the elements read its kinematics (one pass instead of two).
        if !rows_evaluated
            && self.forces.needs_kinematics()
            && !self.sys.constraints().is_empty()
            && self.sys.formulation() != Formulation::Embedded
        {
            self.sys.evaluate_rows(t, q, v);
            rows_evaluated = true;
        }
        self.apply_with(t, q, v, rows_evaluated);
        // `formulation: auto` takes the multiplier form here: the same q̈ as the embedded form
        // (tests/it/propagation_formulations.rs), 1.08–1.7× faster on every bundled scene
        // (docs/performance.md). Least squares (λ = S⁺ r) where stages or drift make redundant
        // rows disagree (`DynamicsOptions::stage`).
        let opts = DynamicsOptions {
            rows_evaluated,
            gains: Some(self.gains),
            t,
            ..DynamicsOptions::stage(self.sys.formulation())
        };
        let result = self
            .sys
            .forward_dynamics_with(q, v, self.tau, opts)
            .map(|a| qdd.copy_from_slice(a.as_slice()));
        let kkt = self.sys.multipliers();
        if result.is_ok() && disagree_beyond_rounding(kkt.inconsistency, kkt.b.amax()) {
            self.least_squares += 1;
        }
        match result {
            Ok(()) => Ok(()),
            Err(Error::InconsistentConstraints { .. }) => {
                // At a singular configuration the acceleration rows disagree by the drift:
                // satisfy the independent ones (counted in `Trajectory::least_squares_evaluations`).
                self.least_squares += 1;
                self.ls
                    .least_squares_accel(self.sys, self.gains, (t, q, v), self.tau, qdd)
                    .map(|_| ())
            }
            Err(e) => Err(e),
        }
    }

    /// Analytic: the derivatives of the constrained (or free) forward dynamics at the applied τ,
    /// plus ∂q̈/∂τ · ∂τ/∂(q, v) of the continuous controllers and of the force elements — their
    /// joint spring-dampers in closed form, any other element's generalized force by central
    /// differences (kinematics only: a point spring's geometric stiffness included). Falls back to
    /// differences of the whole right-hand side where the derivatives are not available (a kind
    /// without them, or a singular configuration).
    fn accel_jacobian(
        &mut self,
        model: &Model,
        (t, q, v): (f64, &[f64], &[f64]),
        qdd: &[f64],
        jac: &mut DMatrix<f64>,
        scratch: &mut JacobianScratch,
    ) -> Result<bool> {
        let nv = v.len();
        // The derivatives (or differences) evaluate at other states: nothing to reuse after.
        self.rows.t = None;
        self.apply(t, q, v);
        let rows = self.sys.constraints().nrows;
        let dd = (self.jw.dd).get_or_insert_with(|| DerivativeData::new(model, rows));
        // Where the dynamics are a constant form, its own derivatives: the exact Jacobian of
        // the right-hand side evaluated (dynamics/invariant.rs).
        let analytic = match self.invariant {
            Some(form) if self.gains == Baumgarte::default() => {
                form.derivatives(v, &mut dd.dqdd_dq, &mut dd.dqdd_dv, &mut dd.dqdd_dtau);
                Ok(())
            }
            _ => dynamics_derivatives(self.sys, stage_options(t, self.gains), dd, q, v, self.tau),
        };
        if analytic.is_err() {
            accel_jacobian_fd(self, model, (t, q, v), qdd, jac, scratch)?;
            return Ok(false);
        }
        for r in 0..nv {
            for c in 0..nv {
                jac[(nv + r, c)] = dd.dqdd_dq[(r, c)];
                jac[(nv + r, nv + c)] = dd.dqdd_dv[(r, c)];
            }
        }
        // A joint spring-damper −k q − d v moves q̈ by ∂q̈/∂τ_j (−k, −d) on its joint's
        // columns (1-DOF: its tangent column is its v index); the continuous controllers'
        // feedback (the same form) is added last, onto the F kept without it.
        if self.forces.depends_on_state_by_joints_only() {
            for &(_, iv, k, d, _) in self.forces.joint_spring_dampers() {
                for r in 0..nv {
                    let g = dd.dqdd_dtau[(r, iv)];
                    jac[(nv + r, iv)] -= g * k;
                    jac[(nv + r, nv + iv)] -= g * d;
                }
            }
        } else {
            self.force_columns_fd((t, q, v), jac);
        }
        let dd = self.jw.dd.as_ref().expect("checked above");
        scratch.keep_passive(jac, dd.dqdd_dtau.as_slice());
        scratch.dqdd_dt.iter_mut().for_each(|x| *x = 0.0);
        if let Some(a) = self.control {
            scratch.apply_controllers(a, (t, q, v), jac);
        }
        Ok(true)
    }
}
