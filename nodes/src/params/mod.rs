//! The nodes' parameters as typed structs: units in the doc comments, unknown keys refused,
//! validated before anything is built.
//!
//! A node's parameters are [`NodeParams<K>`]: the groups every node kind has ([`CommonParams`]:
//! `enabled`, `use_sim_time`, `model.*`, `state.*`, `frames.*`, `slip.*`, `network.*`,
//! `diagnostics.*`, `payload.*`) and the
//! kind's own struct `K` (its module: `crate::predictor::PredictorParams`, …). The common groups
//! let one `/**:` section of a parameter file set what all nodes share; kind-specific keys go
//! under the node's own name. As ROS parameters the nested keys are dotted
//! (`model.scene_file`, `slip.friction_coefficient`).
//!
//! Every struct is `#[serde(deny_unknown_fields, default)]`: a missing key takes the default
//! documented on its field, a misspelt one is an error that names it.

mod groups;
mod kind;
mod payload;
pub mod work;

use std::path::{Path, PathBuf};

use constraint_dynamics::model::Model;
use ros2_client::{Parameter, ParameterValue};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::ros::args::{Parameters, RosArgsError, yaml_to_param};

pub use groups::{
    CommandMsg, CommandParams, CommandType, DiagnosticsParams, Fallback, FramesParams,
    JointNoiseParams, ModelParams, NetworkParams, SlipParams, StaleBehaviour, StateParams,
};
pub use kind::NodeKind;
pub use payload::PayloadParams;
pub use work::WorkBudget;

/// A parameter that is missing, malformed or out of its range.
#[derive(Debug, thiserror::Error)]
pub enum ParamsError {
    /// A value outside its documented range, or an inconsistent group.
    #[error("{name} {reason}")]
    Invalid {
        /// Dotted parameter name.
        name: String,
        /// What is wrong, with the value.
        reason: String,
    },
    /// Parameters that do not fit the typed struct (unknown key, wrong type).
    #[error(transparent)]
    Ros(#[from] RosArgsError),
    /// A parameter that cannot change while the node runs.
    #[error(
        "parameter '{name}' cannot change while the node runs{detail}; restart the node with the new value"
    )]
    Fixed {
        /// The parameter.
        name: String,
        /// Which ones can change.
        detail: String,
    },
}

impl ParamsError {
    /// An out-of-range or inconsistent value of `name`.
    pub fn invalid(name: &str, reason: impl Into<String>) -> Self {
        ParamsError::Invalid {
            name: name.to_string(),
            reason: reason.into(),
        }
    }
}

/// What a node kind's own parameter struct offers.
pub trait KindParams:
    Clone + std::fmt::Debug + Default + PartialEq + Serialize + DeserializeOwned + Send + 'static
{
    /// Parameters that may be changed at run time through `set_parameters` (prefixes of the
    /// dotted names, `.`-terminated for groups). Everything else is fixed once the node runs.
    const DYNAMIC: &'static [&'static str];

    /// Checks every value, naming the parameter that is wrong.
    fn validate(&self) -> Result<(), ParamsError>;

    /// Checks the values that size work against the scene's work limits (when the node is
    /// configured and on every run-time set), naming the parameter and its limit. Default:
    /// nothing sizes work.
    fn check_work(&self, _budget: &WorkBudget) -> Result<(), ParamsError> {
        Ok(())
    }

    /// Checks the values that name parts of the model (coordinates) against it, when the
    /// node is configured and on every run-time set. Default: none do.
    fn check_model(&self, _model: &Model) -> Result<(), ParamsError> {
        Ok(())
    }
}

/// The groups every node kind has.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommonParams {
    /// Create this node when the suite starts.
    pub enabled: bool,
    /// Stamp messages and run timers on /clock (ROS standard parameter).
    pub use_sim_time: bool,
    /// Configure and activate the node at start (lifecycle); false = wait, unconfigured, for a
    /// lifecycle manager's `~/change_state`.
    pub autostart: bool,
    /// Where the robot comes from.
    pub model: ModelParams,
    /// Where the latest state comes from.
    pub state: StateParams,
    /// Frame names of the published messages.
    pub frames: FramesParams,
    /// When a rolling contact counts as slipping.
    pub slip: SlipParams,
    /// Where the DDS participant may talk.
    pub network: NetworkParams,
    /// The node's status on `/diagnostics`.
    pub diagnostics: DiagnosticsParams,
    /// A payload the robot carries (default: the scene's `payload:`); changeable at run time.
    pub payload: PayloadParams,
}

impl Default for CommonParams {
    fn default() -> Self {
        CommonParams {
            enabled: true,
            use_sim_time: false,
            autostart: true,
            model: ModelParams::default(),
            state: StateParams::default(),
            frames: FramesParams::default(),
            slip: SlipParams::default(),
            network: NetworkParams::default(),
            diagnostics: DiagnosticsParams::default(),
            payload: PayloadParams::default(),
        }
    }
}

/// The top-level keys of [`CommonParams`] (the rest belong to the kind's struct).
const COMMON_KEYS: [&str; 10] = [
    "enabled",
    "use_sim_time",
    "autostart",
    "model",
    "state",
    "frames",
    "slip",
    "network",
    "diagnostics",
    "payload",
];

/// Parameters no kind may change at run time: `use_sim_time` and `autostart` are read once.
const NEVER_DYNAMIC: [&str; 2] = ["use_sim_time", "autostart"];

/// Parameters every kind may change at run time (besides its own [`KindParams::DYNAMIC`]): the
/// payload rebuilds the model.
pub const COMMON_DYNAMIC: [&str; 1] = ["payload."];

impl CommonParams {
    /// Checks every value, naming the parameter that is wrong.
    pub fn validate(&self) -> Result<(), ParamsError> {
        if self.model.scene_file.trim().is_empty() {
            return Err(ParamsError::invalid(
                "model.scene_file",
                "is required: a scene file such as params/suite_mobile_manipulator.yaml",
            ));
        }
        if self.model.use_robot_description {
            nonempty(
                "model.robot_description_topic",
                &self.model.robot_description_topic,
            )?;
        }
        nonempty("frames.odom_frame", &self.frames.odom_frame)?;
        self.state.validate()?;
        nonneg("slip.friction_coefficient", self.slip.friction_coefficient)?;
        nonneg("slip.planar_normal_force", self.slip.planar_normal_force)?;
        crate::ros::context::NetworkConfig::default()
            .with_interfaces_param(&self.network.interfaces)
            .map_err(|e| ParamsError::invalid("network.interfaces", e.to_string()))?;
        self.diagnostics.validate()?;
        self.payload.validate()
    }
}

/// One node's parameters: the common groups and the kind's own.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeParams<K> {
    /// What every node kind has.
    pub common: CommonParams,
    /// What this kind adds.
    pub node: K,
}

impl<K: KindParams> NodeParams<K> {
    /// Typed parameters from ROS parameters; unknown keys and bad values are errors.
    pub fn from_parameters(params: &Parameters) -> Result<Self, ParamsError> {
        let serde_yaml::Value::Mapping(all) = params.to_yaml() else {
            return Err(ParamsError::invalid("parameters", "are not a mapping"));
        };
        let (mut common, mut node) = (serde_yaml::Mapping::new(), serde_yaml::Mapping::new());
        for (k, v) in all {
            let is_common = k.as_str().is_some_and(|k| COMMON_KEYS.contains(&k));
            if is_common { &mut common } else { &mut node }.insert(k, v);
        }
        let p = NodeParams {
            common: Parameters::deserialize_value(serde_yaml::Value::Mapping(common))?,
            node: Parameters::deserialize_value(serde_yaml::Value::Mapping(node))?,
        };
        p.validate()?;
        Ok(p)
    }

    /// Checks every value, naming the parameter that is wrong.
    pub fn validate(&self) -> Result<(), ParamsError> {
        self.common.validate()?;
        self.node.validate()
    }

    /// The parameters as ROS parameters (dotted names), to declare on the node so that
    /// `ros2 param list/get` show them.
    pub fn to_ros(&self) -> Vec<(String, ParameterValue)> {
        let mut out = Vec::new();
        for v in [
            serde_yaml::to_value(&self.common),
            serde_yaml::to_value(&self.node),
        ] {
            flatten(&v.unwrap_or(serde_yaml::Value::Null), "", &mut out);
        }
        out.sort_by(|a, b| a.0.cmp(&b.0));
        out
    }

    /// Checks the values that name parts of `model`: `payload.frame` and the kind's own
    /// ([`KindParams::check_model`]).
    pub fn check_model(&self, model: &Model) -> Result<(), ParamsError> {
        let frame = self.common.payload.frame.as_str();
        if !frame.is_empty() && !model.frames.iter().any(|f| f.name == frame) {
            let known: Vec<&str> = model.frames.iter().map(|f| f.name.as_str()).collect();
            return Err(ParamsError::invalid(
                "payload.frame",
                format!(
                    "= '{frame}' is not a frame of the model (known frames: {})",
                    known.join(", ")
                ),
            ));
        }
        self.node.check_model(model)
    }

    /// Whether this kind has parameter `name`: one of the names it declares, or a key of a
    /// map-valued group (`state.joint_noise.joints.<joint>`, empty by default).
    pub fn has(name: &str) -> bool {
        fn walk(m: &serde_yaml::Mapping, prefix: &str, name: &str) -> bool {
            m.iter().any(|(k, v)| {
                let full = format!("{prefix}{}", k.as_str().unwrap_or_default());
                match v {
                    // An empty group in the defaults is a map whose keys the user chooses.
                    serde_yaml::Value::Mapping(m) if m.is_empty() => name
                        .strip_prefix(&full)
                        .and_then(|rest| rest.strip_prefix('.'))
                        .is_some_and(|key| !key.is_empty()),
                    serde_yaml::Value::Mapping(m) => walk(m, &format!("{full}."), name),
                    _ => full == name,
                }
            })
        }
        let d = Self::default();
        [
            serde_yaml::to_value(&d.common),
            serde_yaml::to_value(&d.node),
        ]
        .iter()
        .any(|v| matches!(v, Ok(serde_yaml::Value::Mapping(m)) if walk(m, "", name)))
    }

    /// The parameters with every parameter of one set request applied (`changes`), if each
    /// name may change at run time and the combination is valid — within the scene's work
    /// limits too when the node has a scene (`budget`). `current` holds every parameter's
    /// present value. Rules between parameters (`payload.*`, `acceleration_limits.*`) are
    /// judged on the combination, so a request may change several together.
    pub fn updated(
        current: &Parameters,
        changes: &[Parameter],
        budget: Option<&WorkBudget>,
    ) -> Result<Self, ParamsError> {
        let mut params = current.clone();
        for Parameter { name, value } in changes {
            let dynamic = |d: &&str| name == *d || (d.ends_with('.') && name.starts_with(d));
            let mut allowed = K::DYNAMIC.iter().chain(COMMON_DYNAMIC.iter());
            if NEVER_DYNAMIC.contains(&name.as_str()) || !allowed.any(dynamic) {
                let all: Vec<&str> = K::DYNAMIC.iter().chain(&COMMON_DYNAMIC).copied().collect();
                return Err(ParamsError::Fixed {
                    name: name.to_string(),
                    detail: format!(" (run-time changes: {})", all.join(", ")),
                });
            }
            params.values.insert(name.to_string(), value.clone());
        }
        let p = Self::from_parameters(&params)?;
        if let Some(b) = budget {
            p.node.check_work(b)?;
        }
        Ok(p)
    }
}

fn flatten(v: &serde_yaml::Value, prefix: &str, out: &mut Vec<(String, ParameterValue)>) {
    match v {
        serde_yaml::Value::Mapping(m) => {
            for (k, v) in m {
                let key = k.as_str().unwrap_or_default();
                let name = if prefix.is_empty() {
                    key.to_string()
                } else {
                    format!("{prefix}.{key}")
                };
                flatten(v, &name, out);
            }
        }
        other => {
            if let Ok(p) = yaml_to_param(prefix, other) {
                out.push((prefix.to_string(), p));
            }
        }
    }
}

/// `x` finite and > 0.
pub(crate) fn positive(name: &str, x: f64) -> Result<(), ParamsError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(ParamsError::invalid(
            name,
            format!("= {x} must be positive and finite"),
        ))
    }
}

/// `x` finite and ≥ 0.
pub(crate) fn nonneg(name: &str, x: f64) -> Result<(), ParamsError> {
    if x.is_finite() && x >= 0.0 {
        Ok(())
    } else {
        Err(ParamsError::invalid(
            name,
            format!("= {x} must be finite and ≥ 0"),
        ))
    }
}

/// `s` not blank.
pub(crate) fn nonempty(name: &str, s: &str) -> Result<(), ParamsError> {
    if s.trim().is_empty() {
        Err(ParamsError::invalid(name, "must not be empty"))
    } else {
        Ok(())
    }
}

/// Resolves a scene path: absolute as is; relative in the working directory, else next to a
/// parameter file (the last one given first).
pub fn resolve_path(path: &str, params_files: &[PathBuf]) -> PathBuf {
    let p = Path::new(path);
    if p.is_absolute() || p.exists() {
        return p.to_path_buf();
    }
    for f in params_files.iter().rev() {
        if let Some(dir) = f.parent() {
            let candidate = dir.join(p);
            if candidate.exists() {
                return candidate;
            }
        }
    }
    p.to_path_buf()
}

#[cfg(test)]
mod set_tests;
#[cfg(test)]
mod tests;
