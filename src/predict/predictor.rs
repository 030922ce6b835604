//! The predictor: a configuration built once from a scene, the workspace its runs reuse, and
//! one entry point that takes a [`PredictionRequest`] and returns a [`Trajectory`].
//!
//! The configuration ([`PredictorConfig`]: integration settings, process noise, the scene's
//! controllers at rest and drift gains) never changes after it is built; what would change it
//! builds a new predictor. A run owns its own state: the controllers' integrators start from the
//! configuration's at every call, and the drift gains a run uses are resolved from the
//! configuration, never saved and restored around it.

use super::InvariantDynamics;
use super::contacts::ContactJudge;
use super::covariance::UncertaintySpec;
use super::covariance::worker::PipeSlot;
use super::drift::DriftProjector;
use super::estimate::{self, Lane, MAX_REFINEMENTS};
use super::request::{IntegrationOverrides, PredictionBudget, PredictionRequest};
use super::run::rhs::JacobianWork;
use super::settings::{DriftControl, IntegrationSettings};
use super::trajectory::Trajectory;
use crate::actuators::Actuators;
use crate::algorithm::innovations_product;
use crate::dynamics::{Baumgarte, TreeKktWorkspace};
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::limits::EvaluationCost;
use crate::model::Model;
use crate::system::System;
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;
use std::time::Instant;

/// What a predictor is configured with, fixed once built.
#[derive(Clone, Debug)]
pub struct PredictorConfig {
    /// `integration:` of the scene (validated).
    pub(super) settings: IntegrationSettings,
    /// `uncertainty:` of the scene (process noise of the covariance).
    pub(super) uncertainty: UncertaintySpec,
    /// The scene's controllers at rest: every run starts its own copy from these.
    pub(super) actuators: Actuators,
    /// The scene's own Baumgarte gains (`dynamics:`); zero gains under `drift: baumgarte` take
    /// the time constant `baumgarte_steps` × dt of each run's step.
    pub(super) gains: Baumgarte,
    /// Propagate the covariance on a second thread when the machine has more than one core
    /// (covariance/worker.rs; the same P to the bit).
    pub(super) parallel_covariance: bool,
    /// The constrained dynamics as a constant form, where it depends on no coordinate (the
    /// stages evaluate it instead of the full dynamics; dynamics/invariant.rs).
    pub(super) invariant: Option<InvariantDynamics>,
}

impl PredictorConfig {
    /// The integration settings.
    pub fn settings(&self) -> &IntegrationSettings {
        &self.settings
    }

    /// The process noise of the covariance.
    pub fn uncertainty(&self) -> &UncertaintySpec {
        &self.uncertainty
    }

    /// The scene's controllers at rest.
    pub fn actuators(&self) -> &Actuators {
        &self.actuators
    }

    /// The controllers' period [s], None without controllers or with continuous ones.
    pub fn control_period(&self) -> Option<f64> {
        (!self.actuators.is_empty() && !self.actuators.is_continuous())
            .then_some(self.actuators.control_period)
    }
}

/// Buffers of a run, sized once per model (the stepping loop allocates nothing).
#[derive(Clone, Debug, Default)]
pub(super) struct Workspace {
    /// The answer (0) and the error estimate's companion (1) (estimate.rs).
    pub(super) lanes: [Lane; 2],
    /// Tangent-space difference of the two lanes' q (nv).
    pub(super) diff: Vec<f64>,
    /// Least-squares constrained accelerations at singular configurations.
    pub(super) ls: DriftProjector,
    pub(super) tau: Vec<f64>,
    pub(super) tau_act: Vec<f64>,
    /// The companion's own controllers and their torque: feedback acts on the state it is
    /// computed from, so each lane closes its own loop (with the answer's torques the companion
    /// would run open-loop and drift away along any unstable mode — an arm held up by its PD).
    pub(super) companion_actuators: Actuators,
    pub(super) tau_companion: Vec<f64>,
    pub(super) zero: Vec<f64>,
    /// The state and applied force at the start of a step (covariance propagation).
    pub(super) qn: Vec<f64>,
    pub(super) vn: Vec<f64>,
    pub(super) tau_n: Vec<f64>,
    /// The continuous controllers' torque at the current stage (nv).
    pub(super) tau_ctl: Vec<f64>,
    /// q̈ probed where a frozen continuous controller heads back inside its effort (nv), at
    /// (t, `probe_q`, `probe_v`): the next step's first evaluation there takes it.
    pub(super) probe_qdd: Vec<f64>,
    pub(super) probe_t: Option<f64>,
    pub(super) probe_q: Vec<f64>,
    pub(super) probe_v: Vec<f64>,
    /// The state the drift projection left with its rows evaluated (run/advance.rs, `RowsAt`).
    pub(super) rows_q: Vec<f64>,
    pub(super) rows_v: Vec<f64>,
    /// The implicit methods' Jacobian (run/advance.rs).
    pub(super) jw: JacobianWork,
    /// Work units of one dynamics evaluation on each path.
    pub(super) cost: EvaluationCost,
    /// The Baumgarte gains of the current run (`Predictor::drift_gains`).
    pub(super) gains: Baumgarte,
    /// The covariance worker's pipe while a run has one.
    pub(super) pipe: PipeSlot,
}

/// A scene's predictor: an immutable [`PredictorConfig`] and the workspace of its runs.
#[derive(Clone, Debug)]
pub struct Predictor {
    pub(super) config: PredictorConfig,
    /// Model, constraints and the dynamics' workspaces.
    pub(super) sys: System,
    /// The scene's force elements (with their Jacobian scratch).
    pub(super) forces: ForceElements,
    /// The run's controllers: a copy of the configuration's, started afresh by every run.
    pub(super) actuators: Actuators,
    pub(super) covariance: Option<super::covariance::CovariancePropagator>,
    /// The model the system evaluates (the same `Arc`).
    pub(super) model: Arc<Model>,
    pub(super) ws: Workspace,
    /// The scene's contacts, judged at every sample with forces (contacts.rs).
    pub(super) contact_judge: ContactJudge,
}

impl Predictor {
    /// Build from its parts, validating the integration settings; no process noise (see
    /// [`Predictor::with_uncertainty`]).
    pub fn new(
        mut sys: System,
        forces: ForceElements,
        actuators: Actuators,
        settings: IntegrationSettings,
    ) -> Result<Self> {
        settings.validate()?;
        check_lateral_tyres(&sys, &forces)?;
        let neutral = sys.model().neutral();
        let invariant = InvariantDynamics::fit(&mut sys, &neutral);
        let model = sys.model().clone();
        let (nq, nv) = (model.nq, model.nv);
        let ws = Workspace {
            lanes: [Lane::new(&sys), Lane::new(&sys)],
            diff: vec![0.0; nv],
            ls: DriftProjector::new(&sys),
            tau: vec![0.0; nv],
            tau_act: vec![0.0; nv],
            companion_actuators: Actuators::default(),
            tau_companion: vec![0.0; nv],
            zero: vec![0.0; nv],
            qn: vec![0.0; nq],
            vn: vec![0.0; nv],
            tau_n: vec![0.0; nv],
            tau_ctl: vec![0.0; nv],
            probe_qdd: vec![0.0; nv],
            probe_t: None,
            probe_q: vec![0.0; nq],
            probe_v: vec![0.0; nv],
            rows_q: vec![0.0; nq],
            rows_v: vec![0.0; nv],
            cost: EvaluationCost::of(&sys),
            gains: sys.baumgarte(),
            jw: JacobianWork::new(&sys),
            pipe: PipeSlot::default(),
        };
        let config = PredictorConfig {
            settings,
            uncertainty: UncertaintySpec::default(),
            actuators: actuators.clone(),
            gains: sys.baumgarte(),
            parallel_covariance: true,
            invariant,
        };
        let contact_judge = ContactJudge::new(&model, sys.constraints());
        Ok(Self {
            config,
            contact_judge,
            sys,
            forces,
            actuators,
            covariance: None,
            model,
            ws,
        })
    }

    /// The same predictor configured with the integration settings `edit` makes of these
    /// (validated, naming the field).
    pub fn with_settings(mut self, edit: impl FnOnce(&mut IntegrationSettings)) -> Result<Self> {
        edit(&mut self.config.settings);
        self.config.settings.validate()?;
        Ok(self)
    }

    /// The same predictor with the covariance's process noise `uncertainty`.
    pub fn with_uncertainty(mut self, uncertainty: UncertaintySpec) -> Self {
        self.config.uncertainty = uncertainty;
        self
    }

    /// The same predictor propagating the covariance beside the prediction on a second thread
    /// (`true`, the default, where the machine has more than one core) or inline (`false`).
    pub fn with_parallel_covariance(mut self, parallel: bool) -> Self {
        self.config.parallel_covariance = parallel;
        self
    }

    /// [`Self::with_parallel_covariance`] on this predictor, for its next predictions.
    pub fn set_parallel_covariance(&mut self, parallel: bool) {
        self.config.parallel_covariance = parallel;
    }

    /// The configuration.
    pub fn config(&self) -> &PredictorConfig {
        &self.config
    }

    /// The robot model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The work budget of a request with these overrides: its settings (validated) and limits.
    pub fn budget(&self, overrides: &IntegrationOverrides) -> Result<PredictionBudget> {
        let control = match (self.config.control_period(), overrides.control_period) {
            (Some(_), Some(p)) => Some(p),
            (c, _) => c,
        };
        Ok(
            PredictionBudget::validated(overrides.apply(&self.config.settings), control)?
                .with_system(&self.sys),
        )
    }

    /// Propagate the request's start state over its horizon under its commands: samples of q,
    /// v, the held actuator torques, residuals, energies, the error estimate, and on request
    /// the constraint forces and the covariance. Checked before running: the state, the
    /// commands and the work ([`PredictionBudget::check`]).
    pub fn predict(&mut self, req: &PredictionRequest) -> Result<Trajectory> {
        let start = Instant::now();
        crate::limits::check_input_state(&self.model, req.q0, req.v0, &self.ws.zero)?;
        if req.forces {
            super::contacts::validate(&req.contact_limits)?;
        }
        let budget = self.budget(&req.integration)?;
        if budget.settings().drift == DriftControl::None {
            check_turn_gain_drift(self.sys.constraints())?;
        }
        let horizon = budget.horizon(req.horizon);
        budget.check(horizon)?;
        for (t, c) in req.commands {
            crate::error::check_finite("command time", &[*t])?;
            self.actuators.check_command(c)?;
        }
        if !req.controller_integrals.is_empty() {
            if req.controller_integrals.len() != self.model.nv {
                return Err(Error::Invalid(format!(
                    "controller_integrals: {} values for {} velocity coordinates",
                    req.controller_integrals.len(),
                    self.model.nv
                )));
            }
            crate::error::check_finite("controller_integrals", req.controller_integrals)?;
        }
        let control = budget.control_period();
        let mut s = budget.settings().clone();
        let mut refinements = 0;
        let result = loop {
            self.ws.gains = self.drift_gains(&s);
            match self.run(req, horizon, &s, control) {
                // `adapt`: rerun with the step or tolerance the estimate asks for, bounded.
                Err(Error::ErrorEstimateExceeded { t, excess, .. })
                    if s.adapt && refinements < MAX_REFINEMENTS =>
                {
                    s = estimate::refined(&s, excess, t, horizon);
                    PredictionBudget::new(s.clone(), control)
                        .with_system(&self.sys)
                        .check(horizon)?;
                    refinements += 1;
                }
                r => break r,
            }
        };
        let mut traj = result?;
        traj.refinements = refinements;
        traj.run_time_s = start.elapsed().as_secs_f64();
        Ok(traj)
    }

    /// The Baumgarte gains of a run under `s`: the scene's, or under `drift: baumgarte` without
    /// gains of its own, the time constant `baumgarte_steps` × dt.
    fn drift_gains(&self, s: &IntegrationSettings) -> Baumgarte {
        let scene = self.config.gains;
        match s.drift == DriftControl::Baumgarte && scene == Baumgarte::default() {
            true => Baumgarte::from_time_constant(s.baumgarte_steps * s.dt),
            false => scene,
        }
    }

    /// Refuse, before running, a fixed explicit step beyond the method's stability limit for the
    /// stiffest spring or damper: dt·max(ω, d/m) from k (M⁻¹)_ii, d (M⁻¹)_ii per joint element.
    /// The mobilities a M⁻¹ aᵀ come from ABA's factors on a tree that takes the linear path (one
    /// O(n) pass per row), from the dense inverse of M elsewhere; a scene without force elements
    /// has no rate to bound.
    pub(super) fn check_step_size(
        &mut self,
        q: &[f64],
        v: &[f64],
        s: &IntegrationSettings,
    ) -> Result<()> {
        let Some(limit) = s.method.integrator().stability_limit() else {
            return Ok(());
        };
        if self.forces.is_empty() {
            return Ok(());
        }
        self.sys.kinematics_at(q, v);
        let rate = match self.tree_max_rate(q) {
            Some(rate) => rate,
            None => {
                let m = self.sys.mass_matrix_at(q).clone();
                let reg = m.diagonal().amax().max(1e-12) * 1e-12;
                let minv = (m + DMatrix::identity(v.len(), v.len()) * reg)
                    .try_inverse()
                    .unwrap_or_default();
                let mut mobility = |a: &[f64]| {
                    let a = DVector::from_column_slice(a);
                    a.dot(&(&minv * &a))
                };
                (self.forces).max_rate(self.sys.model(), self.sys.data(), &mut mobility)
            }
        };
        if s.dt * rate > limit {
            return Err(Error::StepTooLarge {
                message: format!(
                    "dt = {} s exceeds the {:?} stability limit {:.3e} s for the stiffest force element \
                     (rate {rate:.3e} 1/s); use a smaller dt or method sdirk2",
                    s.dt,
                    s.method,
                    limit / rate
                ),
            });
        }
        Ok(())
    }

    /// The elements' fastest rate with the mobilities from ABA's factors of M at q (the
    /// system's kinematics at (q, v), kept: the factors go into a copy of its data), O(n) per
    /// row; None where the system takes the dense path or a pivot fails its checks.
    fn tree_max_rate(&mut self, q: &[f64]) -> Option<f64> {
        if !self.sys.takes_linear_path() {
            return None;
        }
        let model = self.sys.model();
        let mut factors = self.sys.data().clone();
        let mut kkt = TreeKktWorkspace::new(model);
        if !kkt.factor_metric(model, &mut factors, q) {
            return None;
        }
        let mut u = vec![0.0; model.nv];
        let mut mobility = |a: &[f64]| {
            kkt.innovations(model, &factors, a, &mut u);
            innovations_product(model, &factors, &u, &u)
        };
        Some((self.forces).max_rate(model, self.sys.data(), &mut mobility))
    }
}

/// A rolling contact whose sideways grip is a tyre's (`lateral: tyre`) has no lateral row: the
/// wheel's `forces.tyres` entry (with an axis) must hold it, or it would slide freely.
fn check_lateral_tyres(sys: &System, forces: &ForceElements) -> Result<()> {
    for (c, name) in sys.constraints().items.iter().zip(&sys.constraints().names) {
        if let crate::constraints::Constraint::Rolling(rc) = c
            && rc.lateral_free()
            && !forces.has_wheel_tyre(rc.wheel)
        {
            return Err(Error::Invalid(format!(
                "constraint '{name}': lateral: tyre needs a forces.tyres entry with an axis on \
                 its wheel '{}'",
                sys.model().frames[rc.wheel].name
            )));
        }
    }
    Ok(())
}

/// A rolling contact with a turn gain is held at its current offset over each evaluation, and
/// only the drift control moves its contact point as the turn rate changes (constraints/rolling.rs).
fn check_turn_gain_drift(set: &crate::constraints::ConstraintSet) -> Result<()> {
    let with_gain = set.items.iter().position(|c| {
        matches!(c, crate::constraints::Constraint::Rolling(rc) if rc.axle_offset_turn_gain != 0.0)
    });
    match with_gain {
        Some(k) => Err(Error::Invalid(format!(
            "constraint '{}': axle_offset_turn_gain needs drift control (integration.drift: \
             projection or baumgarte): only the drift control takes back the slip a change of \
             turn rate leaves",
            set.names[k]
        ))),
        None => Ok(()),
    }
}
