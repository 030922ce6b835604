//! `cd_predictor`'s own parameters.

use serde::{Deserialize, Serialize};

pub use super::monitor_params::MonitorParams;
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
    /// The acceleration envelope (`~/acceleration_limits`) and its velocity smoother bridge.
    pub envelope: EnvelopeParams,
    /// Scoring past predictions against what arrives (`~/prediction_residuals`).
    pub monitor: MonitorParams,
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
            envelope: EnvelopeParams::default(),
            monitor: MonitorParams::default(),
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
        self.markers.validate()?;
        self.envelope.validate()?;
        self.monitor.validate()
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

/// `envelope.*`: the acceleration envelope at the prediction's start state, published every
/// tick on `~/acceleration_limits`, and the optional bridge that keeps a Nav2 velocity
/// smoother's `max_accel` and `max_decel` at it (`docs/ros2.md`, "Acceleration limits"). Fixed
/// while the node runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnvelopeParams {
    /// Compute the envelope and publish `~/acceleration_limits`
    /// (`constraint_dynamics_msgs/AccelerationLimits`).
    pub enabled: bool,
    /// Node name of a Nav2 velocity smoother whose `max_accel` and `max_decel` follow the
    /// envelope through its `<name>/set_parameters` service (relative names resolve in this
    /// node's namespace); "" = no bridge.
    pub velocity_smoother: String,
    /// Relative change of any sent value that is worth a new `set_parameters` [-] (in [0, 1)).
    pub dead_band: f64,
    /// Least time between two sends that only loosen the limits [s] (> 0); a send that
    /// tightens one goes at once.
    pub min_interval: f64,
    /// Forward limits at or below this (≤ 0: the robot cannot hold that direction with every
    /// contact; infeasible) are sent as this [m/s²] (> 0: a smoother needs max_accel > 0,
    /// max_decel < 0).
    pub linear_floor: f64,
    /// The same for the yaw limits [rad/s²] (> 0).
    pub angular_floor: f64,
    /// The scene whose limits the envelope checks, "" = the predictor's own. A planar base has
    /// no normal rows: a floating variant of the same robot with its supports as contacts
    /// (`params/suite_mobile_manipulator_floating.yaml`) checks lift-off and friction too. Its
    /// state is the predictor's: the base pose and twist, and every joint by name.
    pub scene_file: String,
}

impl Default for EnvelopeParams {
    fn default() -> Self {
        EnvelopeParams {
            enabled: true,
            velocity_smoother: String::new(),
            dead_band: 0.05,
            min_interval: 1.0,
            linear_floor: 0.05,
            angular_floor: 0.1,
            scene_file: String::new(),
        }
    }
}

impl EnvelopeParams {
    /// Checks every value, naming the one that is wrong.
    pub fn validate(&self) -> Result<(), ParamsError> {
        if !(0.0..1.0).contains(&self.dead_band) {
            return Err(ParamsError::invalid(
                "envelope.dead_band",
                format!("= {} must be in [0, 1)", self.dead_band),
            ));
        }
        positive("envelope.min_interval", self.min_interval)?;
        positive("envelope.linear_floor", self.linear_floor)?;
        positive("envelope.angular_floor", self.angular_floor)?;
        let name = &self.velocity_smoother;
        if name.is_empty() {
            return Ok(());
        }
        if !self.enabled {
            return Err(ParamsError::invalid(
                "envelope.velocity_smoother",
                format!("= '{name}' needs envelope.enabled: true"),
            ));
        }
        let service = format!("{name}/set_parameters");
        crate::ros::context::topic_name("/", "cd_predictor", &service).map_err(|e| {
            ParamsError::invalid(
                "envelope.velocity_smoother",
                format!("= '{name}' is not a ROS node name: {e}"),
            )
        })?;
        Ok(())
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
