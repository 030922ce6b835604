//! Bounds on the parameters that size a node's work, so that no value a parameter file or
//! `ros2 param set` gives can make one cycle's work unbounded (a `horizon` of 1e9 s would spin
//! a core until killed).
//!
//! Two layers, both refusing with the parameter and its range named:
//! - static ranges, checked with every other value ([`super::KindParams::validate`]): `rate`,
//!   `horizon`, `max_horizon`, `max_commands`, `max_rollouts`, `max_rollout_samples`,
//!   `rollout_threads`, `diagnostics.period`, the footprint's size;
//! - the scene's work limits ([`WorkBudget`], checked when the node is configured and on every
//!   run-time set): a prediction's steps (horizon / dt for the fixed-step methods, horizon /
//!   `actuators.control_period`) within `integration.max_steps` and its samples (horizon /
//!   `integration.sample_period`) within `integration.max_samples` — the core's own limits
//!   (`PredictionBudget::check`), so a horizon the node accepts is one the core runs —
//!   and, for the periodic predictor, `rate` × steps per prediction within
//!   `integration.max_steps` per second.

use constraint_dynamics::Scene;
use constraint_dynamics::limits::show;
use constraint_dynamics::predict::{IntegrationSettings, PredictionBudget};

use super::ParamsError;

/// The predictor's `rate` [Hz]: at most 1 kHz (a tick is a whole prediction), at least one
/// per 100 s.
pub const RATE: (f64, f64) = (0.01, 1000.0);
/// The predictor's `horizon` and the prediction service's `max_horizon` [s], whatever the scene
/// (the scene's limits usually bound them lower: [`WorkBudget::max_horizon`]).
pub const MAX_HORIZON: f64 = 3600.0;
/// The prediction service's `max_commands`.
pub const MAX_COMMANDS: u32 = 1_000_000;
/// The prediction service's `max_rollouts` (Nav2 MPPI's `batch_size` is 2000 by default).
pub const MAX_ROLLOUTS: u32 = 100_000;
/// The prediction service's `max_rollout_samples`: 1e7 poses, twists and stamps ≈ 1 GB of reply.
pub const MAX_ROLLOUT_SAMPLES: u32 = 10_000_000;
/// The prediction service's `rollout_threads`.
pub const MAX_THREADS: u32 = 1024;
/// `diagnostics.period` [s]: a status at most every 10 ms.
pub const DIAGNOSTICS_PERIOD: (f64, f64) = (0.01, 3600.0);
/// Vertices of `markers.footprint` (each is drawn at every outline of every prediction).
pub const MAX_FOOTPRINT_VERTICES: usize = 256;

/// A count within [lo, hi], or an error naming `name`, the value and the range.
pub(crate) fn count_in_range(name: &str, n: u32, (lo, hi): (u32, u32)) -> Result<(), ParamsError> {
    if (lo..=hi).contains(&n) {
        return Ok(());
    }
    Err(ParamsError::invalid(
        name,
        format!("= {n} is outside its range [{lo}, {hi}]"),
    ))
}

/// `x` finite and within [lo, hi], or an error naming `name`, the value and the range.
pub(crate) fn in_range(
    name: &str,
    x: f64,
    range: (f64, f64),
    unit: &str,
) -> Result<(), ParamsError> {
    let (lo, hi) = range;
    if x.is_finite() && x >= lo && x <= hi {
        return Ok(());
    }
    Err(ParamsError::invalid(
        name,
        format!(
            "= {} {unit} is outside its range [{}, {}] {unit}",
            show(x),
            show(lo),
            show(hi)
        ),
    ))
}

/// What one prediction on a scene may cost: the core's budget of the scene's predictions
/// ([`PredictionBudget`]), capped by [`MAX_HORIZON`]; the node names the parameter it refuses.
#[derive(Clone, Debug)]
pub struct WorkBudget {
    core: PredictionBudget,
}

impl WorkBudget {
    /// The budget of `scene`'s predictions.
    pub fn of(scene: &Scene) -> WorkBudget {
        WorkBudget {
            core: scene.prediction_budget(),
        }
    }

    /// A budget from parts (tests).
    pub fn new(integration: IntegrationSettings, control_period: Option<f64>) -> WorkBudget {
        WorkBudget {
            core: PredictionBudget::new(integration, control_period),
        }
    }

    /// The horizon of a prediction [s]: `requested`, or the scene's `integration.horizon`.
    pub fn horizon(&self, requested: Option<f64>) -> f64 {
        self.core.horizon(requested)
    }

    /// The longest horizon one prediction may run [s]: [`MAX_HORIZON`] and the core's
    /// [`PredictionBudget::max_horizon`] at `rate` [Hz].
    pub fn max_horizon(&self, rate: Option<f64>) -> f64 {
        MAX_HORIZON.min(self.core.max_horizon(rate))
    }

    /// Refuses a `horizon` [s] (parameter `name`) over [`WorkBudget::max_horizon`], naming the
    /// limits that set it.
    pub fn check_horizon(
        &self,
        name: &str,
        horizon: f64,
        rate: Option<f64>,
    ) -> Result<(), ParamsError> {
        let max = self.max_horizon(rate);
        if horizon <= max && self.core.check(horizon).is_ok() {
            return Ok(());
        }
        let s = self.core.settings();
        let step = match (!s.method.is_adaptive(), self.core.control_period()) {
            (true, Some(p)) => format!(
                "integration.dt {} s, actuators.control_period {} s",
                show(s.dt),
                show(p)
            ),
            (true, None) => format!("integration.dt {} s", show(s.dt)),
            (false, Some(p)) => format!("actuators.control_period {} s", show(p)),
            (false, None) => format!("integration.sample_period {} s", show(s.sample_period)),
        };
        let per_rate = match rate {
            Some(r) => format!(
                "; at rate {} Hz, rate × steps per prediction may not exceed integration.max_steps per second",
                show(r)
            ),
            None => String::new(),
        };
        Err(ParamsError::invalid(
            name,
            format!(
                "= {} s is beyond its limit of {} s on this scene: one prediction may take \
                 integration.max_steps = {} steps (horizon / {step}) and integration.max_samples \
                 = {} samples (horizon / integration.sample_period {} s){per_rate}; shorten it \
                 or raise the scene's integration limits",
                show(horizon),
                show(max),
                show(s.max_steps),
                show(s.max_samples),
                show(s.sample_period),
            ),
        ))
    }
}

#[cfg(test)]
#[path = "work_tests.rs"]
mod tests;
