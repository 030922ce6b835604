//! What one prediction is asked for ([`PredictionRequest`]), and the one place that resolves and
//! bounds its work ([`PredictionBudget`]): the horizon (none → the scene's), the step, control
//! tick and sample counts, and the work units of the fixed-step methods, all checked before
//! anything runs. The ROS nodes validate their parameters and requests through the same budget,
//! so a horizon a node accepts is one the core runs.

use super::integrators::Method;
use super::settings::{DriftControl, IntegrationSettings};
use crate::actuators::Command;
use crate::constraints::ContactLimits;
use crate::error::{Error, Result};
use crate::limits::{EvaluationCost, show};
use crate::system::System;
use nalgebra::DMatrix;

/// One prediction: where it starts, how long, under which commands, what it records, and any
/// change to the configured integration for this call only.
///
/// ```text
/// PredictionRequest::new(&q0, &v0).horizon(2.0).commands(&cmds).forces(true)
/// ```
#[derive(Clone, Copy, Debug, Default)]
pub struct PredictionRequest<'a> {
    /// Start configuration (nq) [m, rad, unit quaternion].
    pub q0: &'a [f64],
    /// Start velocity (nv) [m/s, rad/s].
    pub v0: &'a [f64],
    /// (start time [s], command), sorted by time; the last one started is in force, none
    /// before the first.
    pub commands: &'a [(f64, Command)],
    /// Horizon [s] (≥ 0); None: the scene's `integration.horizon`.
    pub horizon: Option<f64>,
    /// Changes to the configured integration for this call (method, step, accuracy, …).
    pub integration: IntegrationOverrides,
    /// Start covariance of [δq; δv] (2nv × 2nv, tangent space); None: no covariance.
    pub start_covariance: Option<&'a DMatrix<f64>>,
    /// Record λ, the constraint forces and Jᵀλ in every sample, and judge the contacts at
    /// each (`Sample::contacts`, `Trajectory::contact_check`).
    pub forces: bool,
    /// What the contacts' judgement assumes where a contact declares no μ, or has no normal
    /// row (default: nothing; those limits are listed unchecked). Read only with `forces`.
    pub contact_limits: ContactLimits,
    /// Which samples carry the propagated covariance (with a start covariance).
    pub covariance_samples: CovarianceSamples<'a>,
    /// The velocity controllers' integrals ∫(target − q̇) dt at the start [rad or m], by v
    /// index (nv; a joint without a velocity controller is ignored), e.g. inferred from the
    /// measured efforts ([`crate::actuators::Actuators::integrals_from_efforts`]). Empty: every
    /// controller starts afresh, at zero.
    pub controller_integrals: &'a [f64],
    /// The diff drive's lagged command (v [m/s], ω [rad/s]) at the start, where the scene
    /// declares a `command_lag` ([`crate::actuators::CommandLag`] over the commands before
    /// the start). None: the lag starts on the first command.
    pub lagged_command: Option<[f64; 2]>,
}

/// Which samples of a prediction carry the propagated covariance.
///
/// P is read, brought onto the constraints there, only at those samples; between them its
/// linearized chunks may span several samples (covariance/chunks.rs), so a caller that reads P
/// only at the horizon (a predicted odometry) asks for [`CovarianceSamples::Last`] and pays for
/// a few long chunks instead of one or more per sample. Each read costs nv + 2 constraint
/// evaluations and a factorization of M. What is read at a sample does not depend on which
/// others are (covariance/reading.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum CovarianceSamples<'a> {
    /// Every sample.
    #[default]
    Every,
    /// The last sample only (the horizon); the others carry none.
    Last,
    /// The samples within one sample period of any of these times [s] (so the sample nearest
    /// each, on either side), and the last; the others carry none.
    Near(&'a [f64]),
    /// The samples at these times [s] (within 1e-9 s), and the last; the others carry none.
    At(&'a [f64]),
}

impl CovarianceSamples<'_> {
    /// Whether the sample at `t` [s] carries P, with samples every `period` [s] up to
    /// `horizon` [s].
    pub(crate) fn at(&self, t: f64, period: f64, horizon: f64) -> bool {
        t >= horizon - 1e-12
            || match self {
                Self::Every => true,
                Self::Last => false,
                Self::Near(times) => times.iter().any(|&h| (t - h).abs() <= period + 1e-9),
                Self::At(times) => times.iter().any(|&h| (t - h).abs() <= 1e-9),
            }
    }
}

impl<'a> PredictionRequest<'a> {
    /// A request from (q0, v0) over the scene's horizon, without commands, forces or covariance.
    pub fn new(q0: &'a [f64], v0: &'a [f64]) -> Self {
        Self {
            q0,
            v0,
            ..Self::default()
        }
    }

    /// Over `horizon` [s] instead of the scene's.
    pub fn horizon(mut self, horizon: f64) -> Self {
        self.horizon = Some(horizon);
        self
    }

    /// Under `commands` ((start time [s], command), sorted).
    pub fn commands(mut self, commands: &'a [(f64, Command)]) -> Self {
        self.commands = commands;
        self
    }

    /// With λ and the constraint forces in every sample when `on`.
    pub fn forces(mut self, on: bool) -> Self {
        self.forces = on;
        self
    }

    /// Judging the contacts with `limits` assumed where they declare less.
    pub fn contact_limits(mut self, limits: ContactLimits) -> Self {
        self.contact_limits = limits;
        self
    }

    /// Propagating the covariance from `p0` (2nv × 2nv).
    pub fn covariance(mut self, p0: &'a DMatrix<f64>) -> Self {
        self.start_covariance = Some(p0);
        self
    }

    /// With the covariance in `which` samples.
    pub fn covariance_samples(mut self, which: CovarianceSamples<'a>) -> Self {
        self.covariance_samples = which;
        self
    }

    /// With the velocity controllers' integrals at the start (nv, by v index).
    pub fn controller_integrals(mut self, integrals: &'a [f64]) -> Self {
        self.controller_integrals = integrals;
        self
    }

    /// With these changes to the configured integration.
    pub fn integration(mut self, overrides: IntegrationOverrides) -> Self {
        self.integration = overrides;
        self
    }
}

/// Per-call changes to a predictor's integration settings; each `None` keeps the configured
/// value (the scene's `integration:` and `actuators.control_period`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IntegrationOverrides {
    /// Integration method.
    pub method: Option<Method>,
    /// Step [s] (fixed-step methods; first step of the adaptive ones).
    pub dt: Option<f64>,
    /// Relative tolerance of the adaptive methods.
    pub rtol: Option<f64>,
    /// Absolute tolerance of the adaptive methods [m, rad, m/s or rad/s per entry].
    pub atol: Option<f64>,
    /// Drift control.
    pub drift: Option<DriftControl>,
    /// Output sample period [s].
    pub sample_period: Option<f64>,
    /// The controllers' control period [s]; a scene without controllers has none to change.
    pub control_period: Option<f64>,
    /// Bound on the global error estimate of q, every kind in its own unit [m or rad]
    /// (`f64::INFINITY`: no check); it replaces the scene's per-kind bounds.
    pub max_error: Option<f64>,
    /// Refine the step or tolerances and rerun when the estimate exceeds `max_error`.
    pub adapt: Option<bool>,
    /// Run the error estimate's companion.
    pub error_estimate: Option<bool>,
}

impl IntegrationOverrides {
    /// `settings` with these changes (not validated: [`PredictionBudget::validated`] does).
    pub fn apply(&self, settings: &IntegrationSettings) -> IntegrationSettings {
        let mut s = settings.clone();
        s.method = self.method.unwrap_or(s.method);
        s.dt = self.dt.unwrap_or(s.dt);
        s.rtol = self.rtol.unwrap_or(s.rtol);
        s.atol = self.atol.unwrap_or(s.atol);
        s.drift = self.drift.unwrap_or(s.drift);
        s.sample_period = self.sample_period.unwrap_or(s.sample_period);
        if let Some(x) = self.max_error {
            s.set_max_error(x);
        }
        s.adapt = self.adapt.unwrap_or(s.adapt);
        s.error_estimate = self.error_estimate.unwrap_or(s.error_estimate);
        s
    }
}

/// The work one prediction may do on a configuration: its integration settings and limits,
/// the controllers' period, and the cost of one dynamics evaluation of its model.
#[derive(Clone, Debug)]
pub struct PredictionBudget {
    settings: IntegrationSettings,
    control_period: Option<f64>,
    /// Work units of one dynamics evaluation on each path; None: counts only.
    evaluation_cost: Option<EvaluationCost>,
}

/// The counts of a prediction that fits its budget.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictionWork {
    /// Horizon [s].
    pub horizon_s: f64,
    /// Integration steps of the answer (fixed-step methods; 0 for the adaptive ones, which
    /// count while running).
    pub steps: f64,
    /// Control ticks (0 without controllers).
    pub control_ticks: f64,
    /// Output samples after the first.
    pub samples: f64,
    /// Work units of the fixed-step methods, error estimate included (0 for the others).
    pub work: f64,
}

impl PredictionBudget {
    /// The budget of `settings` with controllers ticking every `control_period` [s] (None: no
    /// controllers); [`PredictionBudget::validated`] also checks the fields.
    pub fn new(settings: IntegrationSettings, control_period: Option<f64>) -> Self {
        Self {
            settings,
            control_period,
            evaluation_cost: None,
        }
    }

    /// [`PredictionBudget::new`] with the settings' fields and the control period validated,
    /// naming the field.
    pub fn validated(settings: IntegrationSettings, control_period: Option<f64>) -> Result<Self> {
        settings.validate_fields()?;
        if let Some(p) = control_period
            && !(p.is_finite() && p > 0.0)
        {
            return Err(Error::Invalid(format!(
                "actuators.control_period = {p} s must be positive"
            )));
        }
        Ok(Self::new(settings, control_period))
    }

    /// The same budget, bounding also the work units of `sys`'s dynamics evaluations on the
    /// path they take ([`EvaluationCost`]).
    pub fn with_system(mut self, sys: &System) -> Self {
        self.evaluation_cost = Some(EvaluationCost::of(sys));
        self
    }

    /// The integration settings.
    pub fn settings(&self) -> &IntegrationSettings {
        &self.settings
    }

    /// The controllers' period [s], None without controllers.
    pub fn control_period(&self) -> Option<f64> {
        self.control_period
    }

    /// The horizon of a request [s]: `requested`, or the scene's `integration.horizon`.
    pub fn horizon(&self, requested: Option<f64>) -> f64 {
        requested.unwrap_or(self.settings.horizon)
    }

    /// Integration steps per second of predicted time: the finest of the fixed step (the
    /// adaptive methods' `dt` is only their first step), the control period and the sample
    /// period (the adaptive methods land on every sample).
    pub fn steps_per_second(&self) -> f64 {
        let s = &self.settings;
        let mut k = 1.0 / s.sample_period;
        if !s.method.is_adaptive() {
            k = k.max(1.0 / s.dt);
        }
        if let Some(p) = self.control_period {
            k = k.max(1.0 / p);
        }
        k
    }

    /// The longest horizon one prediction may run [s] under the step and sample limits, and,
    /// predicting at `rate` [Hz], with `rate` × steps per prediction ≤ `integration.max_steps`
    /// per second.
    pub fn max_horizon(&self, rate: Option<f64>) -> f64 {
        let s = &self.settings;
        let mut h = s.max_samples * s.sample_period;
        if !s.method.is_adaptive() {
            h = h.min(s.max_steps * s.dt);
        }
        if let Some(p) = self.control_period {
            h = h.min(s.max_steps * p);
        }
        if let Some(r) = rate {
            h = h.min(s.max_steps / (r * self.steps_per_second()));
        }
        h
    }

    /// Refuse, before running, a horizon [s] that is negative or not finite, or whose steps
    /// (horizon / dt, horizon / control period), samples (horizon / sample period) or work
    /// (steps × evaluations per step × the model's cost, error estimate included) exceed the
    /// limits; else its counts.
    pub fn check(&self, horizon: f64) -> Result<PredictionWork> {
        if !(horizon.is_finite() && horizon >= 0.0) {
            return Err(Error::Invalid(format!(
                "horizon = {horizon} s must be finite and ≥ 0"
            )));
        }
        let s = &self.settings;
        let limit = |what: String, n: f64, max: f64, hint: &str| {
            if n <= max {
                Ok(n)
            } else {
                Err(Error::WorkLimit {
                    what,
                    estimate: n,
                    limit: max,
                    hint: hint.to_string(),
                })
            }
        };
        let (h, dt) = (show(horizon), show(s.dt));
        // The adaptive methods' dt is only their first step: their steps count while running.
        let fixed = !s.method.is_adaptive();
        let steps = limit(
            format!("integration steps (horizon {h} s / dt {dt} s)"),
            if fixed { horizon / s.dt } else { 0.0 },
            s.max_steps,
            "shorten the horizon, raise dt, or raise integration.max_steps",
        )?;
        let control_ticks = match self.control_period {
            Some(p) => limit(
                format!(
                    "control ticks (horizon {h} s / control_period {} s)",
                    show(p)
                ),
                horizon / p,
                s.max_steps,
                "shorten the horizon, raise actuators.control_period, or raise \
                 integration.max_steps",
            )?,
            None => 0.0,
        };
        let samples = limit(
            format!(
                "output samples (horizon {h} s / sample_period {} s)",
                show(s.sample_period)
            ),
            horizon / s.sample_period,
            s.max_samples,
            "shorten the horizon, raise sample_period, or raise integration.max_samples",
        )?;
        let work = match (
            self.evaluation_cost,
            s.method.integrator().evaluations_per_step(),
        ) {
            (Some(costs), Some(per_step)) => {
                // The error estimate's companion takes two steps of dt/2 per step (estimate.rs):
                // three times the answer's evaluations, counted whether or not it runs.
                let per_step = 3.0 * per_step;
                let steps = (horizon / s.dt).ceil();
                let implicit = s.method.integrator().is_implicit();
                let cost = costs.per_evaluation(implicit);
                let work = steps * per_step * cost;
                limit(
                    format!(
                        "work units ({steps:e} steps × {per_step} evaluations × {cost:.3e} per \
                         evaluation of this {}-body model on its {} path)",
                        costs.bodies,
                        costs.path(implicit)
                    ),
                    work,
                    s.max_work,
                    "shorten the horizon, raise dt, or raise integration.max_work",
                )?
            }
            _ => 0.0,
        };
        Ok(PredictionWork {
            horizon_s: horizon,
            steps,
            control_ticks,
            samples,
            work,
        })
    }
}
