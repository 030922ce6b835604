//! `cd_prediction`'s own parameters.

use serde::{Deserialize, Serialize};

use crate::params::work::{
    MAX_COMMANDS, MAX_HORIZON, MAX_ROLLOUT_SAMPLES, MAX_ROLLOUTS, MAX_THREADS, count_in_range,
    in_range,
};
use crate::params::{CommandParams, KindParams, ParamsError, WorkBudget};

/// The prediction service (`cd_prediction`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PredictionParams {
    /// `fallback` (for requests without commands) and `hold_joints`; `topic`, `stamped` and
    /// `timeout` are not used by this node.
    pub command: CommandParams,
    /// Longest horizon a request may ask for [s].
    pub max_horizon: f64,
    /// Most commands a `~/predict` request may carry.
    pub max_commands: u32,
    /// Most sequences a `~/rollouts` request may carry.
    pub max_rollouts: u32,
    /// Most samples (sequences × sequence length) a `~/rollouts` reply may carry.
    pub max_rollout_samples: u32,
    /// Worker threads of `~/rollouts`; 0: one per core.
    pub rollout_threads: u32,
}

impl Default for PredictionParams {
    fn default() -> Self {
        PredictionParams {
            command: CommandParams::default(),
            max_horizon: 10.0,
            max_commands: 10_000,
            max_rollouts: 2000,
            max_rollout_samples: 200_000,
            rollout_threads: 0,
        }
    }
}

impl KindParams for PredictionParams {
    const DYNAMIC: &'static [&'static str] = &["slip.", "max_horizon", "command.fallback"];

    fn validate(&self) -> Result<(), ParamsError> {
        in_range("max_horizon", self.max_horizon, (1e-3, MAX_HORIZON), "s")?;
        self.command.validate()?;
        count_in_range("max_commands", self.max_commands, (1, MAX_COMMANDS))?;
        count_in_range("max_rollouts", self.max_rollouts, (1, MAX_ROLLOUTS))?;
        count_in_range(
            "max_rollout_samples",
            self.max_rollout_samples,
            (1, MAX_ROLLOUT_SAMPLES),
        )?;
        count_in_range("rollout_threads", self.rollout_threads, (0, MAX_THREADS))
    }

    /// A request of `max_horizon` within the scene's limits.
    fn check_work(&self, budget: &WorkBudget) -> Result<(), ParamsError> {
        budget.check_horizon("max_horizon", self.max_horizon, None)
    }
}
