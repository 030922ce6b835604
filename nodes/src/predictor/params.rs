//! `cd_predictor`'s own parameters.

use serde::{Deserialize, Serialize};

use crate::params::work::{MAX_FOOTPRINT_VERTICES, MAX_HORIZON, RATE, in_range};
use crate::params::{CommandParams, KindParams, ParamsError, WorkBudget, nonempty, positive};

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
    /// rviz2 markers and per-constraint wrenches.
    pub markers: MarkerParams,
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
            markers: MarkerParams::default(),
        }
    }
}

impl PredictorParams {
    /// The horizon a prediction asks for [s]: the parameter, or None (0) for the scene's.
    pub fn horizon(&self) -> Option<f64> {
        (self.horizon > 0.0).then_some(self.horizon)
    }
}

impl KindParams for PredictorParams {
    const DYNAMIC: &'static [&'static str] = &[
        "slip.",
        "state.timeout",
        "state.stale_behaviour",
        "covariance.",
        "horizon",
        "command.timeout",
        "command.fallback",
        "markers.force_scale",
        "markers.arrow_width",
        "markers.footprint",
    ];

    fn validate(&self) -> Result<(), ParamsError> {
        in_range("rate", self.rate, RATE, "Hz")?;
        in_range("horizon", self.horizon, (0.0, MAX_HORIZON), "s")?;
        self.command.validate()?;
        nonempty("command.topic", &self.command.topic)?;
        let c = &self.covariance;
        positive("covariance.position_floor", c.position_floor)?;
        positive("covariance.orientation_floor", c.orientation_floor)?;
        positive("covariance.twist_floor", c.twist_floor)?;
        self.markers.validate()
    }

    /// The horizon (the scene's when 0) within the scene's limits, at `rate`.
    fn check_work(&self, budget: &WorkBudget) -> Result<(), ParamsError> {
        let name = match self.horizon() {
            Some(_) => "horizon",
            None => "horizon (0: the scene's integration.horizon)",
        };
        budget.check_horizon(name, budget.horizon(self.horizon()), Some(self.rate))
    }
}

/// `covariance.*`: the predicted odometry's covariance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CovarianceParams {
    /// Propagate the start covariance (`/odom`'s, `state.joint_noise`) through the prediction
    /// (the core's step linearization: several times the cost of the prediction alone); false =
    /// the floors and the error estimate only, as a prediction without covariance.
    pub propagate: bool,
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
            propagate: true,
            position_floor: 1e-3,
            orientation_floor: 1e-3,
            twist_floor: 1e-3,
        }
    }
}

/// `markers.*`: what rviz2 is shown (`~/markers`, `~/wrench/<constraint>`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MarkerParams {
    /// Publish `~/markers` (`visualization_msgs/MarkerArray`): force arrows and the predicted
    /// footprint.
    pub enabled: bool,
    /// Force arrow length per newton [m/N] (run-time).
    pub force_scale: f64,
    /// Force arrow shaft diameter [m]; footprint lines are half as wide (run-time).
    pub arrow_width: f64,
    /// The robot's footprint polygon in the base frame, flat `[x0, y0, x1, y1, …]` [m], at
    /// least three vertices; the default is the bundled robots' chassis (run-time).
    pub footprint: Vec<f64>,
    /// Time between two footprint outlines along the predicted path [s] (run-time).
    pub footprint_period: f64,
    /// Also publish each constraint's wrench as `geometry_msgs/WrenchStamped` on
    /// `~/wrench/<constraint name>`, in the constraint's frame about its origin.
    pub wrenches: bool,
}

impl Default for MarkerParams {
    fn default() -> Self {
        MarkerParams {
            enabled: true,
            force_scale: 0.01,
            arrow_width: 0.02,
            // urdf/mobile_manipulator.urdf and diff_drive.urdf: chassis 0.4 × 0.3 m centred
            // 5 cm behind base_link.
            footprint: vec![0.15, 0.15, -0.25, 0.15, -0.25, -0.15, 0.15, -0.15],
            footprint_period: 0.2,
            wrenches: false,
        }
    }
}

impl MarkerParams {
    /// Checks every value, naming the one that is wrong.
    pub fn validate(&self) -> Result<(), ParamsError> {
        positive("markers.force_scale", self.force_scale)?;
        positive("markers.arrow_width", self.arrow_width)?;
        positive("markers.footprint_period", self.footprint_period)?;
        let f = &self.footprint;
        if f.len() < 6 || !f.len().is_multiple_of(2) || f.iter().any(|x| !x.is_finite()) {
            return Err(ParamsError::invalid(
                "markers.footprint",
                format!(
                    "= {f:?} must be [x0, y0, x1, y1, …] with at least three finite vertices [m]"
                ),
            ));
        }
        if f.len() > 2 * MAX_FOOTPRINT_VERTICES {
            return Err(ParamsError::invalid(
                "markers.footprint",
                format!(
                    "has {} vertices, more than its limit of {MAX_FOOTPRINT_VERTICES}",
                    f.len() / 2
                ),
            ));
        }
        Ok(())
    }

    /// `footprint` as vertices.
    pub fn polygon(&self) -> Vec<[f64; 2]> {
        self.footprint
            .chunks_exact(2)
            .map(|c| [c[0], c[1]])
            .collect()
    }
}
