//! `cd_prediction`'s own parameters.

use serde::{Deserialize, Serialize};

use crate::params::work::{MAX_COMMANDS, MAX_HORIZON, in_range};
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
    /// Most commands a request may carry.
    pub max_commands: u32,
}

impl Default for PredictionParams {
    fn default() -> Self {
        PredictionParams {
            command: CommandParams::default(),
            max_horizon: 10.0,
            max_commands: 10_000,
        }
    }
}

impl KindParams for PredictionParams {
    const DYNAMIC: &'static [&'static str] = &["slip.", "max_horizon", "command.fallback"];

    fn validate(&self) -> Result<(), ParamsError> {
        in_range("max_horizon", self.max_horizon, (1e-3, MAX_HORIZON), "s")?;
        self.command.validate()?;
        if self.max_commands == 0 || self.max_commands > MAX_COMMANDS {
            return Err(ParamsError::invalid(
                "max_commands",
                format!(
                    "= {} is outside its range [1, {MAX_COMMANDS}]",
                    self.max_commands
                ),
            ));
        }
        Ok(())
    }

    /// A request of `max_horizon` within the scene's limits.
    fn check_work(&self, budget: &WorkBudget) -> Result<(), ParamsError> {
        budget.check_horizon("max_horizon", self.max_horizon, None)
    }
}
