//! `cd_predictor`'s own parameters.

use serde::{Deserialize, Serialize};

use crate::params::{CommandParams, KindParams, ParamsError, nonempty, nonneg, positive};

/// The periodic predictor (`cd_predictor`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PredictorParams {
    /// How commands become the prediction's input.
    pub command: CommandParams,
    /// The predicted odometry's covariance.
    pub covariance: CovarianceParams,
    /// Prediction and publication rate [Hz].
    pub rate: f64,
    /// Prediction horizon [s]; 0 = the scene's `integration.horizon`.
    pub horizon: f64,
    /// Publish `~/predicted_path`.
    pub publish_path: bool,
    /// Publish `~/constraint_forces` (at the current state, with slip flags).
    pub publish_forces: bool,
}

impl Default for PredictorParams {
    fn default() -> Self {
        PredictorParams {
            command: CommandParams::default(),
            covariance: CovarianceParams::default(),
            rate: 10.0,
            horizon: 0.0,
            publish_path: true,
            publish_forces: true,
        }
    }
}

impl KindParams for PredictorParams {
    const DYNAMIC: &'static [&'static str] = &[
        "slip.",
        "covariance.",
        "horizon",
        "command.timeout",
        "command.fallback",
    ];

    fn validate(&self) -> Result<(), ParamsError> {
        positive("rate", self.rate)?;
        nonneg("horizon", self.horizon)?;
        self.command.validate()?;
        nonempty("command.topic", &self.command.topic)?;
        let c = &self.covariance;
        positive("covariance.position_floor", c.position_floor)?;
        positive("covariance.orientation_floor", c.orientation_floor)?;
        positive("covariance.twist_floor", c.twist_floor)
    }
}

/// `covariance.*`: the predicted odometry's covariance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CovarianceParams {
    /// Standard deviation added to the prediction's error estimate for x, y, z [m] (> 0: the
    /// covariance is never zero; the integrator's estimate does not cover model error).
    pub position_floor: f64,
    /// The same for the three rotations [rad] (> 0).
    pub orientation_floor: f64,
    /// Standard deviation of the predicted twist [m/s, rad/s] (> 0; not estimated).
    pub twist_floor: f64,
}

impl Default for CovarianceParams {
    fn default() -> Self {
        CovarianceParams {
            position_floor: 1e-3,
            orientation_floor: 1e-3,
            twist_floor: 1e-3,
        }
    }
}
