//! The nodes' parameters as typed structs: units in the doc comments, unknown keys refused,
//! validated before anything is built.
//!
//! Each node kind has its own struct ([`PredictorParams`], [`ForcesParams`],
//! [`ProjectionParams`], [`PredictionParams`]). They share nested groups (`model.*`,
//! `state.*`, `frames.*`, `slip.*`, `network.*`) so that one `/**:` section of a parameter file
//! can set what all nodes have in common; kind-specific keys go under the node's own name.
//! As ROS parameters the nested keys are dotted (`model.scene_file`, `slip.friction_coefficient`).
//!
//! Every struct is `#[serde(deny_unknown_fields, default)]`: a missing key takes the default
//! documented on its field, a misspelt one is an error that names it.

use std::path::{Path, PathBuf};

use ros2_client::ParameterValue;
use serde::{Deserialize, Serialize};

use crate::ros_args::{Parameters, RosArgsError, yaml_to_param};

/// The four node kinds of the suite.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NodeKind {
    /// Periodic prediction from the latest state and command: `~/predicted_odom`,
    /// `~/predicted_path`, `~/constraint_forces`.
    Predictor,
    /// `~/get_constraint_forces` service.
    Forces,
    /// `~/project_velocity` service and the command filter.
    Projection,
    /// `~/predict` service.
    Prediction,
}

impl NodeKind {
    /// All kinds, in the order the suite starts them.
    pub const ALL: [NodeKind; 4] = [
        NodeKind::Predictor,
        NodeKind::Forces,
        NodeKind::Projection,
        NodeKind::Prediction,
    ];

    /// The `--node` switch value.
    pub fn key(self) -> &'static str {
        match self {
            NodeKind::Predictor => "predictor",
            NodeKind::Forces => "forces",
            NodeKind::Projection => "projection",
            NodeKind::Prediction => "prediction",
        }
    }

    /// The default ROS node name.
    pub fn default_node_name(self) -> &'static str {
        match self {
            NodeKind::Predictor => "cd_predictor",
            NodeKind::Forces => "cd_forces",
            NodeKind::Projection => "cd_projection",
            NodeKind::Prediction => "cd_prediction",
        }
    }

    /// From a `--node` value (`predictor`, `forces`, `projection`, `prediction`).
    pub fn from_key(key: &str) -> Option<NodeKind> {
        NodeKind::ALL.into_iter().find(|k| k.key() == key)
    }

    /// Parameters that may be changed at run time through `set_parameters` (prefixes of the
    /// dotted names). Everything else is fixed once the node runs (restart to change it).
    pub fn dynamic_parameters(self) -> &'static [&'static str] {
        match self {
            NodeKind::Predictor => &[
                "slip.",
                "covariance.",
                "horizon",
                "command.timeout",
                "command.fallback",
            ],
            NodeKind::Forces => &["slip."],
            NodeKind::Projection => &["acceleration_limits.", "filter.accel_limit_dt"],
            NodeKind::Prediction => &["slip.", "max_horizon", "command.fallback"],
        }
    }
}

/// `model.*`: where the robot comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelParams {
    /// Scene file (YAML, `docs/robots.md`): URDF, base type, constraints, actuators, integration
    /// settings. A relative path is looked up in the working directory, then next to each
    /// `--params-file`. Required.
    pub scene_file: String,
    /// Replace the scene's URDF by the one published on `robot_description_topic` whenever it
    /// changes (the scene file still gives base, constraints, actuators).
    pub use_robot_description: bool,
    /// `std_msgs/String` topic with the URDF (reliable, transient local, as
    /// robot_state_publisher publishes it).
    pub robot_description_topic: String,
}

impl Default for ModelParams {
    fn default() -> Self {
        ModelParams {
            scene_file: String::new(),
            use_robot_description: true,
            robot_description_topic: "/robot_description".into(),
        }
    }
}

/// `state.*`: where the latest state comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StateParams {
    /// `sensor_msgs/JointState` topic: joint positions [rad, m], velocities [rad/s, m/s],
    /// efforts [N·m, N] by joint name ("" = do not subscribe).
    pub joint_states_topic: String,
    /// `nav_msgs/Odometry` topic: base pose in the odom frame and twist in the base frame
    /// ("" = do not subscribe).
    pub odom_topic: String,
    /// Before use, project the latest state onto the constraints (mass-weighted, as the
    /// predictor's drift control does), so that noisy wheel and base velocities agree.
    pub project_to_constraints: bool,
    /// With `use_latest_state` and no torques in a `get_constraint_forces` request, take the
    /// joint torques from the last `JointState.effort` [N·m, N].
    pub use_measured_effort: bool,
}

impl Default for StateParams {
    fn default() -> Self {
        StateParams {
            joint_states_topic: "/joint_states".into(),
            odom_topic: "/odom".into(),
            project_to_constraints: true,
            use_measured_effort: true,
        }
    }
}

/// `frames.*`: frame names of the published messages (REP-105).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FramesParams {
    /// The fixed frame: `header.frame_id` of predicted odometry and paths, and the frame the
    /// core's "world" axes are reported in (constraint forces).
    pub odom_frame: String,
    /// `child_frame_id` of the predicted odometry (its twist is in this frame); "" = the
    /// URDF's root link. `/odom` is read as the pose of this frame too.
    pub base_frame: String,
}

impl Default for FramesParams {
    fn default() -> Self {
        FramesParams {
            odom_frame: "odom".into(),
            base_frame: String::new(),
        }
    }
}

/// `slip.*`: when a rolling contact counts as slipping.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlipParams {
    /// Friction coefficient μ [-]: slipping when tangential force > μ · normal force.
    pub friction_coefficient: f64,
    /// Normal force per rolling contact when the model has no normal row (planar base) [N];
    /// 0 = m·|g| / number of rolling contacts (an upper bound when a caster carries load).
    pub planar_normal_force: f64,
}

impl Default for SlipParams {
    fn default() -> Self {
        SlipParams {
            friction_coefficient: 0.8,
            planar_normal_force: 0.0,
        }
    }
}

/// `network.*`: where the DDS participant may talk. One participant per process, so every
/// node of a suite must agree.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NetworkParams {
    /// Network interfaces: comma-separated IP addresses, or `localhost`; "" = all interfaces,
    /// as ROS does (unless `CD_ROS_INTERFACES` / `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`).
    pub interfaces: String,
    /// Allow DDS on interfaces other than loopback. Without it (or
    /// `CD_ALLOW_EXTERNAL_NETWORK=1`) the suite refuses to start on all interfaces unless it
    /// runs inside a loopback-only network namespace (`tools/ros2/netns_run.sh`).
    pub allow_external: bool,
}

/// `command.*`: how base commands become a prediction's input.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommandParams {
    /// Velocity command topic (predictor only): `geometry_msgs/Twist`, or `TwistStamped`
    /// with `stamped`. The diff drive follows linear.x [m/s] and angular.z [rad/s].
    pub topic: String,
    /// The command topic carries `geometry_msgs/TwistStamped` (Nav2's default) [bool].
    pub stamped: bool,
    /// A command older than this is replaced by `fallback` [s].
    pub timeout: f64,
    /// Without a fresh command: `stop` (zero twist, as diff_drive_controller does on timeout),
    /// `hold` (keep the current base twist) or `coast` (wheel controllers off).
    pub fallback: String,
    /// Command every joint that has a position controller in the scene to hold its position at
    /// the start of the prediction.
    pub hold_joints: bool,
}

impl Default for CommandParams {
    fn default() -> Self {
        CommandParams {
            topic: "/cmd_vel".into(),
            stamped: false,
            timeout: 0.5,
            fallback: "stop".into(),
            hold_joints: true,
        }
    }
}

/// What happens without a fresh command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fallback {
    /// Zero base twist.
    Stop,
    /// The current base twist.
    Hold,
    /// No base command (wheel controllers off).
    Coast,
}

impl CommandParams {
    /// `fallback` as an enum.
    pub fn fallback(&self) -> Result<Fallback, String> {
        match self.fallback.as_str() {
            "stop" => Ok(Fallback::Stop),
            "hold" => Ok(Fallback::Hold),
            "coast" => Ok(Fallback::Coast),
            other => Err(format!(
                "command.fallback = {other:?}: expected stop, hold or coast"
            )),
        }
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
}

impl Default for FilterParams {
    fn default() -> Self {
        FilterParams {
            enabled: false,
            input_topic: "/cmd_vel_in".into(),
            output_topic: "/cmd_vel_out".into(),
            stamped: false,
            velocity_limits: true,
            accel_limit_dt: 0.0,
        }
    }
}

/// The periodic predictor (`cd_predictor`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PredictorParams {
    /// Create this node when the suite starts.
    pub enabled: bool,
    /// Stamp messages with /clock (ROS standard parameter).
    pub use_sim_time: bool,
    pub model: ModelParams,
    pub state: StateParams,
    pub frames: FramesParams,
    pub slip: SlipParams,
    pub network: NetworkParams,
    pub command: CommandParams,
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
            enabled: true,
            use_sim_time: false,
            model: ModelParams::default(),
            state: StateParams::default(),
            frames: FramesParams::default(),
            slip: SlipParams::default(),
            network: NetworkParams::default(),
            command: CommandParams::default(),
            covariance: CovarianceParams::default(),
            rate: 10.0,
            horizon: 0.0,
            publish_path: true,
            publish_forces: true,
        }
    }
}

/// The constraint force service (`cd_forces`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ForcesParams {
    /// Create this node when the suite starts.
    pub enabled: bool,
    /// Stamp messages with /clock (ROS standard parameter).
    pub use_sim_time: bool,
    pub model: ModelParams,
    pub state: StateParams,
    pub frames: FramesParams,
    pub slip: SlipParams,
    pub network: NetworkParams,
}

impl Default for ForcesParams {
    fn default() -> Self {
        ForcesParams {
            enabled: true,
            use_sim_time: false,
            model: ModelParams::default(),
            state: StateParams::default(),
            frames: FramesParams::default(),
            slip: SlipParams::default(),
            network: NetworkParams::default(),
        }
    }
}

/// The velocity projection service and command filter (`cd_projection`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProjectionParams {
    /// Create this node when the suite starts.
    pub enabled: bool,
    /// Stamp messages with /clock (ROS standard parameter).
    pub use_sim_time: bool,
    pub model: ModelParams,
    pub state: StateParams,
    pub frames: FramesParams,
    /// Accepted for a shared `/**` section; not used by this node.
    pub slip: SlipParams,
    pub network: NetworkParams,
    /// Offer `~/project_velocity`.
    pub service: bool,
    pub acceleration_limits: AccelerationLimitsParams,
    pub filter: FilterParams,
}

impl Default for ProjectionParams {
    fn default() -> Self {
        ProjectionParams {
            enabled: true,
            use_sim_time: false,
            model: ModelParams::default(),
            state: StateParams::default(),
            frames: FramesParams::default(),
            slip: SlipParams::default(),
            network: NetworkParams::default(),
            service: true,
            acceleration_limits: AccelerationLimitsParams::default(),
            filter: FilterParams::default(),
        }
    }
}

/// The prediction service (`cd_prediction`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PredictionParams {
    /// Create this node when the suite starts.
    pub enabled: bool,
    /// Stamp messages with /clock (ROS standard parameter).
    pub use_sim_time: bool,
    pub model: ModelParams,
    pub state: StateParams,
    pub frames: FramesParams,
    pub slip: SlipParams,
    pub network: NetworkParams,
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
            enabled: true,
            use_sim_time: false,
            model: ModelParams::default(),
            state: StateParams::default(),
            frames: FramesParams::default(),
            slip: SlipParams::default(),
            network: NetworkParams::default(),
            command: CommandParams::default(),
            max_horizon: 10.0,
            max_commands: 10_000,
        }
    }
}

/// One node's parameters, by kind.
#[derive(Clone, Debug, PartialEq)]
pub enum NodeParams {
    Predictor(PredictorParams),
    Forces(ForcesParams),
    Projection(ProjectionParams),
    Prediction(PredictionParams),
}

/// The groups every kind has.
pub struct Common<'a> {
    pub enabled: bool,
    pub model: &'a ModelParams,
    pub state: &'a StateParams,
    pub frames: &'a FramesParams,
    pub slip: &'a SlipParams,
    pub network: &'a NetworkParams,
}

impl NodeParams {
    /// Typed parameters of `kind` from ROS parameters; unknown keys and bad values are errors.
    pub fn from_parameters(kind: NodeKind, params: &Parameters) -> Result<Self, String> {
        let err = |e: RosArgsError| format!("{}: {e}", kind.default_node_name());
        let p = match kind {
            NodeKind::Predictor => NodeParams::Predictor(params.deserialize().map_err(err)?),
            NodeKind::Forces => NodeParams::Forces(params.deserialize().map_err(err)?),
            NodeKind::Projection => NodeParams::Projection(params.deserialize().map_err(err)?),
            NodeKind::Prediction => NodeParams::Prediction(params.deserialize().map_err(err)?),
        };
        p.validate()?;
        Ok(p)
    }

    /// The defaults of `kind`.
    pub fn defaults(kind: NodeKind) -> Self {
        match kind {
            NodeKind::Predictor => NodeParams::Predictor(Default::default()),
            NodeKind::Forces => NodeParams::Forces(Default::default()),
            NodeKind::Projection => NodeParams::Projection(Default::default()),
            NodeKind::Prediction => NodeParams::Prediction(Default::default()),
        }
    }

    pub fn kind(&self) -> NodeKind {
        match self {
            NodeParams::Predictor(_) => NodeKind::Predictor,
            NodeParams::Forces(_) => NodeKind::Forces,
            NodeParams::Projection(_) => NodeKind::Projection,
            NodeParams::Prediction(_) => NodeKind::Prediction,
        }
    }

    /// The shared groups.
    pub fn common(&self) -> Common<'_> {
        macro_rules! common {
            ($p:expr) => {
                Common {
                    enabled: $p.enabled,
                    model: &$p.model,
                    state: &$p.state,
                    frames: &$p.frames,
                    slip: &$p.slip,
                    network: &$p.network,
                }
            };
        }
        match self {
            NodeParams::Predictor(p) => common!(p),
            NodeParams::Forces(p) => common!(p),
            NodeParams::Projection(p) => common!(p),
            NodeParams::Prediction(p) => common!(p),
        }
    }

    /// Mutable `model.scene_file` (resolved to a path by the suite).
    pub fn scene_file_mut(&mut self) -> &mut String {
        match self {
            NodeParams::Predictor(p) => &mut p.model.scene_file,
            NodeParams::Forces(p) => &mut p.model.scene_file,
            NodeParams::Projection(p) => &mut p.model.scene_file,
            NodeParams::Prediction(p) => &mut p.model.scene_file,
        }
    }

    /// The command settings (defaults for kinds without them).
    pub fn command(&self) -> CommandParams {
        match self {
            NodeParams::Predictor(p) => p.command.clone(),
            NodeParams::Prediction(p) => p.command.clone(),
            _ => CommandParams::default(),
        }
    }

    /// Checks every value, naming the parameter that is wrong.
    pub fn validate(&self) -> Result<(), String> {
        let c = self.common();
        if c.model.scene_file.trim().is_empty() {
            return Err(
                "model.scene_file is required: a scene file such as params/suite_mobile_manipulator.yaml"
                    .into(),
            );
        }
        if c.model.use_robot_description {
            nonempty(
                "model.robot_description_topic",
                &c.model.robot_description_topic,
            )?;
        }
        nonempty("frames.odom_frame", &c.frames.odom_frame)?;
        nonneg("slip.friction_coefficient", c.slip.friction_coefficient)?;
        nonneg("slip.planar_normal_force", c.slip.planar_normal_force)?;
        crate::ros_context::NetworkConfig::default()
            .with_interfaces_param(&c.network.interfaces)
            .map_err(|e| format!("network.interfaces: {e}"))?;
        let command = |cmd: &CommandParams| -> Result<(), String> {
            positive("command.timeout", cmd.timeout)?;
            cmd.fallback().map(|_| ())
        };
        match self {
            NodeParams::Predictor(p) => {
                positive("rate", p.rate)?;
                nonneg("horizon", p.horizon)?;
                command(&p.command)?;
                nonempty("command.topic", &p.command.topic)?;
                positive("covariance.position_floor", p.covariance.position_floor)?;
                positive(
                    "covariance.orientation_floor",
                    p.covariance.orientation_floor,
                )?;
                positive("covariance.twist_floor", p.covariance.twist_floor)?;
            }
            NodeParams::Forces(_) => {}
            NodeParams::Projection(p) => {
                let a = &p.acceleration_limits;
                if a.names.len() != a.values.len() {
                    return Err(format!(
                        "acceleration_limits: {} names but {} values",
                        a.names.len(),
                        a.values.len()
                    ));
                }
                for (n, v) in a.names.iter().zip(&a.values) {
                    positive(&format!("acceleration_limits ({n})"), *v)?;
                }
                nonneg("filter.accel_limit_dt", p.filter.accel_limit_dt)?;
                if p.filter.enabled {
                    nonempty("filter.input_topic", &p.filter.input_topic)?;
                    nonempty("filter.output_topic", &p.filter.output_topic)?;
                }
            }
            NodeParams::Prediction(p) => {
                positive("max_horizon", p.max_horizon)?;
                command(&p.command)?;
                if p.max_commands == 0 {
                    return Err("max_commands must be at least 1".into());
                }
            }
        }
        Ok(())
    }

    /// The parameters as ROS parameters (dotted names), to declare on the node so that
    /// `ros2 param list/get` show them.
    pub fn to_ros(&self) -> Vec<(String, ParameterValue)> {
        let value = match self {
            NodeParams::Predictor(p) => serde_yaml::to_value(p),
            NodeParams::Forces(p) => serde_yaml::to_value(p),
            NodeParams::Projection(p) => serde_yaml::to_value(p),
            NodeParams::Prediction(p) => serde_yaml::to_value(p),
        }
        .unwrap_or(serde_yaml::Value::Null);
        let mut out = Vec::new();
        flatten(&value, "", &mut out);
        out
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

fn positive(name: &str, x: f64) -> Result<(), String> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(format!("{name} = {x} must be positive and finite"))
    }
}

fn nonneg(name: &str, x: f64) -> Result<(), String> {
    if x.is_finite() && x >= 0.0 {
        Ok(())
    } else {
        Err(format!("{name} = {x} must be finite and ≥ 0"))
    }
}

fn nonempty(name: &str, s: &str) -> Result<(), String> {
    if s.trim().is_empty() {
        Err(format!("{name} must not be empty"))
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
mod tests {
    use super::*;
    use crate::ros_args::parse_params_yaml;

    #[test]
    fn defaults_validate_once_a_scene_is_given() {
        for kind in NodeKind::ALL {
            let mut p = NodeParams::defaults(kind);
            assert!(p.validate().unwrap_err().contains("model.scene_file"));
            *p.scene_file_mut() = "x.yaml".into();
            p.validate().unwrap();
            assert_eq!(NodeKind::from_key(kind.key()), Some(kind));
        }
    }

    #[test]
    fn nested_keys_shared_section_and_unknown_keys() {
        let yaml = r#"
/**:
  ros__parameters:
    model: { scene_file: s.yaml }
    slip: { friction_coefficient: 0.5 }
cd_predictor:
  ros__parameters:
    rate: 20.0
    command: { stamped: true, fallback: hold }
cd_forces:
  ros__parameters:
    rate: 20.0
"#;
        let p = parse_params_yaml(yaml, "/cd_predictor").unwrap();
        let NodeParams::Predictor(pp) =
            NodeParams::from_parameters(NodeKind::Predictor, &p).unwrap()
        else {
            unreachable!()
        };
        assert_eq!(pp.rate, 20.0);
        assert_eq!(pp.slip.friction_coefficient, 0.5);
        assert!(pp.command.stamped);
        assert_eq!(pp.command.fallback().unwrap(), Fallback::Hold);
        assert_eq!(pp.model.scene_file, "s.yaml");
        assert_eq!(pp.state.joint_states_topic, "/joint_states");
        // `rate` is not a parameter of the forces node.
        let p = parse_params_yaml(yaml, "/cd_forces").unwrap();
        let e = NodeParams::from_parameters(NodeKind::Forces, &p).unwrap_err();
        assert!(e.contains("unknown field `rate`"), "{e}");
    }

    #[test]
    fn bad_values_are_named() {
        let cases = [
            ("rate: 0.0", "rate"),
            (
                "covariance: { position_floor: 0.0 }",
                "covariance.position_floor",
            ),
            ("command: { fallback: brake }", "command.fallback"),
            (
                "slip: { friction_coefficient: -1.0 }",
                "slip.friction_coefficient",
            ),
            ("network: { interfaces: eth0 }", "network.interfaces"),
        ];
        for (body, name) in cases {
            let yaml = format!(
                "cd_predictor:\n  ros__parameters:\n    model: {{ scene_file: s.yaml }}\n    {body}\n"
            );
            let p = parse_params_yaml(&yaml, "/cd_predictor").unwrap();
            let e = NodeParams::from_parameters(NodeKind::Predictor, &p).unwrap_err();
            assert!(e.contains(name), "{body}: {e}");
        }
    }

    #[test]
    fn ros_parameters_round_trip() {
        let mut p = NodeParams::defaults(NodeKind::Projection);
        *p.scene_file_mut() = "s.yaml".into();
        let ros = p.to_ros();
        let get = |n: &str| ros.iter().find(|(k, _)| k == n).map(|(_, v)| v.clone());
        assert_eq!(
            get("model.scene_file"),
            Some(ParameterValue::String("s.yaml".into()))
        );
        assert_eq!(
            get("acceleration_limits.values"),
            Some(ParameterValue::DoubleArray(vec![1.0, 2.0]))
        );
        assert_eq!(get("filter.enabled"), Some(ParameterValue::Boolean(false)));
        let mut params = Parameters::default();
        params.values.extend(ros);
        let back = NodeParams::from_parameters(NodeKind::Projection, &params).unwrap();
        assert_eq!(back, p);
    }
}
