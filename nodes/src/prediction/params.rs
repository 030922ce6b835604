//! `cd_prediction`'s own parameters.

use serde::{Deserialize, Serialize};

use crate::params::{CommandParams, KindParams, ParamsError, positive};

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
        positive("max_horizon", self.max_horizon)?;
        self.command.validate()?;
        if self.max_commands == 0 {
            return Err(ParamsError::invalid("max_commands", "must be at least 1"));
        }
        Ok(())
    }
}
