//! `integration:` of a scene: the integration settings a predictor is configured with, and the
//! drift control they choose.

use super::error_kinds::{ByKind, KIND_KEYS, KIND_NAMES};
use super::integrators::Method;
use serde::{Deserialize, Serialize};

/// How drift from the constraints is controlled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DriftControl {
    /// Nothing: the residuals grow as the integration error makes them.
    None,
    /// Baumgarte terms in the constraint accelerations (gains from `dynamics:` or from
    /// `baumgarte_steps` × dt).
    Baumgarte,
    /// Mass-weighted projection of q (Newton) and v after every step.
    #[default]
    Projection,
}

/// `integration:` in a scene. Defaults: RK4, dt = 1 ms, projection, horizon 1 s, max_error 1e-3
/// on the global error estimate, samples every 10 ms — accurate to ~1e-10 on the bundled scenes at a few µs per step.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct IntegrationSettings {
    /// `method:` semi_implicit_euler | rk4 | dopri5 | dop853 | sdirk2 | radau5 | ros2 (default `rk4`).
    #[serde(default)]
    pub method: Method,
    /// Step [s] (fixed-step methods; first step of the adaptive ones).
    #[serde(default = "default_dt")]
    pub dt: f64,
    /// Relative and absolute tolerances of the adaptive methods (dopri5, dop853, radau5).
    #[serde(default = "default_rtol")]
    pub rtol: f64,
    /// `atol:` absolute tolerance of dopri5 [m, rad, m/s or rad/s per entry] (default 1e-10).
    #[serde(default = "default_atol")]
    pub atol: f64,
    /// `drift:` none | baumgarte | projection (default `projection`).
    #[serde(default)]
    pub drift: DriftControl,
    /// With `drift: baumgarte` and no gains under `dynamics:`, the time constant is this many steps.
    #[serde(default = "default_baumgarte_steps")]
    pub baumgarte_steps: f64,
    /// Default horizon [s].
    #[serde(default = "default_horizon")]
    pub horizon: f64,
    /// Sample period of the output [s].
    #[serde(default = "default_sample")]
    pub sample_period: f64,
    /// Semi-implicit Euler and RK4 on a passive, conservative scene: stop with `Diverged` when
    /// the energy moves by more than this fraction of the energy in motion (`.inf` turns the check
    /// off).
    #[serde(default = "default_max_energy_error")]
    pub max_energy_error: f64,
    /// Integration steps (and control ticks) one prediction may take (default 1e6): checked
    /// before running (horizon / dt, horizon / control period) and while running (dopri5).
    #[serde(default = "default_max_steps")]
    pub max_steps: f64,
    /// Output samples one prediction may hold (default 1e5): horizon / sample_period.
    #[serde(default = "default_max_samples")]
    pub max_samples: f64,
    /// Work units one prediction may cost (default 1e10, ≈ 10–60 s of CPU): dynamics
    /// evaluations × the cost of one on the path it takes, see `limits::EvaluationCost` (the
    /// dense path: bodies + Σ depth² of the coordinates; the linear-time path: O(n m² + m³)
    /// with m constraint rows).
    #[serde(default = "default_max_work")]
    pub max_work: f64,
    /// `max_error:` bound on the global error estimate of q, every kind of coordinate in its
    /// own unit [m or rad] (every sample's `error_estimate_by_kind`, see `estimate.rs`; default
    /// 1e-3, `.inf` turns the check off): a run over it stops with
    /// `Error::ErrorEstimateExceeded` naming the kind and a step or tolerance that meets it.
    #[serde(default = "default_max_error")]
    pub max_error: f64,
    /// `max_error_base_m`, `max_error_base_rad`, `max_error_joint_rad`, `max_error_joint_m`:
    /// the bound on one kind of coordinate's estimate in its own unit (error_kinds.rs: the
    /// base's position [m] and orientation [rad], the joints' angles [rad] and displacements
    /// [m]); each kind not given is bounded by `max_error`, and `max_error: .inf` turns every
    /// check off. [`IntegrationSettings::error_bounds`] resolves them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_error_base_m: Option<f64>,
    /// See `max_error_base_m`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_error_base_rad: Option<f64>,
    /// See `max_error_base_m`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_error_joint_rad: Option<f64>,
    /// See `max_error_base_m`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_error_joint_m: Option<f64>,
    /// `adapt:` when the estimate exceeds `max_error`, refine dt (fixed-step methods) or the
    /// tolerances (dopri5) from the method's order and rerun, at most 4 times (default false).
    #[serde(default)]
    pub adapt: bool,
    /// `error_estimate:` run the error estimate's companion (default true; estimate.rs). It
    /// costs about 2× more evaluations; `false` is for callers that bound the error otherwise
    /// (planner rollouts, a step already validated on the scene): samples then carry no
    /// `error_estimate` and `max_error` / `adapt` cannot act.
    #[serde(default = "default_true")]
    pub error_estimate: bool,
    /// `jacobian_spans:` ROS2 evaluates its F at the start of every this many pieces of
    /// spans (between samples, command starts and a continuous controller's predicted
    /// saturation exit; default 1). The continuous controllers enter F only through their
    /// feedback through ∂q̈/∂τ, kept with each F: a new target re-forms F's ∂q̈/∂t, and a
    /// controller that saturates or comes back inside re-forms F with or without its feedback,
    /// with no new derivatives. A W-method keeps its order with any F; an older one damps the
    /// stiff modes less exactly. Measured on the suite's scene (`jacobian_spans: 5` at 20 ms):
    /// the accuracy against the held reference, the error estimate and the covariance against
    /// Monte Carlo are those of 1 to three digits.
    #[serde(default = "default_jacobian_spans")]
    pub jacobian_spans: usize,
}

fn default_jacobian_spans() -> usize {
    1
}

fn default_true() -> bool {
    true
}

fn default_max_error() -> f64 {
    1e-3
}

fn default_max_steps() -> f64 {
    crate::limits::DEFAULT_MAX_STEPS
}
fn default_max_samples() -> f64 {
    crate::limits::DEFAULT_MAX_SAMPLES
}
fn default_max_work() -> f64 {
    crate::limits::DEFAULT_MAX_WORK
}

fn default_dt() -> f64 {
    1e-3
}
fn default_rtol() -> f64 {
    1e-8
}
fn default_atol() -> f64 {
    1e-10
}
fn default_baumgarte_steps() -> f64 {
    10.0
}
fn default_horizon() -> f64 {
    1.0
}
fn default_sample() -> f64 {
    0.01
}
fn default_max_energy_error() -> f64 {
    0.2
}

impl Default for IntegrationSettings {
    fn default() -> Self {
        Self {
            method: Method::default(),
            dt: default_dt(),
            rtol: default_rtol(),
            atol: default_atol(),
            drift: DriftControl::default(),
            baumgarte_steps: default_baumgarte_steps(),
            horizon: default_horizon(),
            sample_period: default_sample(),
            max_energy_error: default_max_energy_error(),
            max_steps: default_max_steps(),
            max_samples: default_max_samples(),
            max_work: default_max_work(),
            max_error: default_max_error(),
            max_error_base_m: None,
            max_error_base_rad: None,
            max_error_joint_rad: None,
            max_error_joint_m: None,
            adapt: false,
            error_estimate: true,
            jacobian_spans: default_jacobian_spans(),
        }
    }
}

impl IntegrationSettings {
    /// The bound on each kind's error estimate: its own key, else `max_error`; every bound
    /// infinite when `max_error` is (`.inf` turns the check off).
    pub fn error_bounds(&self) -> ByKind {
        if self.max_error == f64::INFINITY {
            return ByKind::uniform(f64::INFINITY);
        }
        let [base_m, base_rad, joint_rad, joint_m] = self.per_kind_max_error();
        let or = |x: Option<f64>| x.unwrap_or(self.max_error);
        ByKind {
            base_m: or(base_m),
            base_rad: or(base_rad),
            joint_rad: or(joint_rad),
            joint_m: or(joint_m),
        }
    }

    /// `max_error = x` bounding every kind in its own unit: the per-kind keys are dropped (the
    /// command line's `--max-error` and a request's override).
    pub fn set_max_error(&mut self, x: f64) {
        self.max_error = x;
        self.max_error_base_m = None;
        self.max_error_base_rad = None;
        self.max_error_joint_rad = None;
        self.max_error_joint_m = None;
    }

    /// The setting that bounds kind `k` (index in `error_kinds::KIND_NAMES`): its own key when
    /// given, else `max_error`.
    pub(super) fn error_bound_key(&self, k: usize) -> &'static str {
        match self.per_kind_max_error()[k] {
            Some(_) => KIND_KEYS[k],
            None => "integration.max_error",
        }
    }

    /// The per-kind keys in the order of `error_kinds::KIND_NAMES`.
    fn per_kind_max_error(&self) -> [Option<f64>; 4] {
        [
            self.max_error_base_m,
            self.max_error_base_rad,
            self.max_error_joint_rad,
            self.max_error_joint_m,
        ]
    }

    /// Refuse settings that cannot work, naming the field, and a scene horizon over the work
    /// limits ([`PredictionBudget`](super::PredictionBudget)).
    pub fn validate(&self) -> crate::Result<()> {
        super::PredictionBudget::validated(self.clone(), None)?.check(self.horizon)?;
        Ok(())
    }

    /// The field checks of [`IntegrationSettings::validate`].
    pub(super) fn validate_fields(&self) -> crate::Result<()> {
        let pos = |name: &str, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(crate::Error::Invalid(format!(
                    "integration.{name} = {x} must be positive and finite"
                )))
            }
        };
        pos("dt", self.dt)?;
        pos("rtol", self.rtol)?;
        pos("atol", self.atol)?;
        pos("baumgarte_steps", self.baumgarte_steps)?;
        pos("sample_period", self.sample_period)?;
        pos("max_steps", self.max_steps)?;
        pos("max_samples", self.max_samples)?;
        pos("max_work", self.max_work)?;
        if self.max_energy_error.is_nan() || self.max_energy_error <= 0.0 {
            return Err(crate::Error::Invalid(format!(
                "integration.max_energy_error = {} must be positive (.inf: no check)",
                self.max_energy_error
            )));
        }
        if self.max_error.is_nan() || self.max_error <= 0.0 {
            return Err(crate::Error::Invalid(format!(
                "integration.max_error = {} must be positive (.inf: no check)",
                self.max_error
            )));
        }
        for (name, x) in KIND_NAMES.iter().zip(self.per_kind_max_error()) {
            if let Some(x) = x.filter(|x| x.is_nan() || *x <= 0.0) {
                return Err(crate::Error::Invalid(format!(
                    "integration.max_error_{name} = {x} must be positive (.inf: no check)"
                )));
            }
        }
        if self.jacobian_spans == 0 {
            return Err(crate::Error::Invalid(
                "integration.jacobian_spans = 0 must be at least 1".into(),
            ));
        }
        if self.adapt && !self.error_estimate {
            return Err(crate::Error::Invalid(
                "integration.adapt needs integration.error_estimate: true (it acts on the estimate)"
                    .into(),
            ));
        }
        if !(self.horizon.is_finite() && self.horizon >= 0.0) {
            return Err(crate::Error::Invalid(format!(
                "integration.horizon = {} must be ≥ 0",
                self.horizon
            )));
        }
        Ok(())
    }
}
