//! `cd_projection`'s own parameters.

use constraint_dynamics::model::Model;
use constraint_dynamics::projection::coordinate_index;
use serde::{Deserialize, Serialize};

use crate::params::{KindParams, ParamsError, nonempty, nonneg, positive};

/// `acceleration_limits.*`: a_max per velocity coordinate for `accel_limit_dt` requests.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AccelerationLimitsParams {
    /// Coordinate names (`v_names`, or the base aliases vx, vy, wz).
    pub names: Vec<String>,
    /// a_max per name [m/s² or rad/s²] (> 0).
    pub values: Vec<f64>,
}

impl Default for AccelerationLimitsParams {
    fn default() -> Self {
        AccelerationLimitsParams {
            names: vec!["vx".into(), "wz".into()],
            values: vec![1.0, 2.0],
        }
    }
}

/// `filter.*`: the velocity projection as a command filter between a planner and the base
/// controller.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FilterParams {
    /// Subscribe `input_topic`, publish the projected command on `output_topic`.
    pub enabled: bool,
    /// Commands in (`geometry_msgs/Twist`, or `TwistStamped` with `stamped`).
    pub input_topic: String,
    /// Feasible commands out (same type as in).
    pub output_topic: String,
    /// Both topics carry `geometry_msgs/TwistStamped`.
    pub stamped: bool,
    /// Apply the URDF joint velocity limits (e.g. wheel speeds).
    pub velocity_limits: bool,
    /// If > 0, also bound |v − v_current| ≤ a_max · accel_limit_dt (see `acceleration_limits`) [s].
    pub accel_limit_dt: f64,
    /// The base controller's control period [s]: if > 0, each command becomes one the robot
    /// can reach within it under its efforts, friction cones and contacts (the dynamic
    /// projection); 0 = the kinematic projection.
    pub control_period: f64,
}

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams {
            enabled: false,
            input_topic: "cmd_vel_in".into(),
            output_topic: "cmd_vel_out".into(),
            stamped: false,
            velocity_limits: true,
            accel_limit_dt: 0.0,
            control_period: 0.0,
        }
    }
}

/// The velocity projection service and command filter (`cd_projection`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProjectionParams {
    /// Offer `~/project_velocity`.
    pub service: bool,
    /// a_max per coordinate for `accel_limit_dt` requests and the filter.
    pub acceleration_limits: AccelerationLimitsParams,
    /// The command filter.
    pub filter: FilterParams,
}

impl Default for ProjectionParams {
    fn default() -> Self {
        ProjectionParams {
            service: true,
            acceleration_limits: AccelerationLimitsParams::default(),
            filter: FilterParams::default(),
        }
    }
}

impl KindParams for ProjectionParams {
    const DYNAMIC: &'static [&'static str] = &[
        "acceleration_limits.",
        "filter.accel_limit_dt",
        "filter.control_period",
    ];

    fn validate(&self) -> Result<(), ParamsError> {
        let a = &self.acceleration_limits;
        if a.names.len() != a.values.len() {
            return Err(ParamsError::invalid(
                "acceleration_limits.values",
                format!(
                    "= {:?} must hold one a_max per name of acceleration_limits.names = {:?} \
                     ({} values for {} names; change both in one request)",
                    a.values,
                    a.names,
                    a.values.len(),
                    a.names.len()
                ),
            ));
        }
        for (n, v) in a.names.iter().zip(&a.values) {
            positive(&format!("acceleration_limits.values ({n})"), *v)?;
        }
        nonneg("filter.accel_limit_dt", self.filter.accel_limit_dt)?;
        nonneg("filter.control_period", self.filter.control_period)?;
        if self.filter.enabled {
            nonempty("filter.input_topic", &self.filter.input_topic)?;
            nonempty("filter.output_topic", &self.filter.output_topic)?;
        }
        Ok(())
    }

    /// Every name of `acceleration_limits.names` a velocity coordinate of the model (or a base
    /// alias).
    fn check_model(&self, model: &Model) -> Result<(), ParamsError> {
        let names = &self.acceleration_limits.names;
        for n in names {
            coordinate_index(model, n).map_err(|e| {
                ParamsError::invalid("acceleration_limits.names", format!("= {names:?}: {e}"))
            })?;
        }
        Ok(())
    }
}
