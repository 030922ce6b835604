//! Parameter groups shared by several node kinds (`model.*`, `state.*`, `command.*`, …), each a
//! typed struct: units in the doc comments, unknown keys refused, defaults documented.

use serde::{Deserialize, Serialize};

use super::{ParamsError, positive};

#[cfg(test)]
#[path = "command_tests.rs"]
mod command_tests;

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
            robot_description_topic: "robot_description".into(),
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
    /// Start each prediction's velocity controllers (the diff drive's wheels) with the integral
    /// that gives the last `JointState.effort` under the command then in force, instead of at
    /// zero: a wheel's PI integral holds the torque its friction and load take. Right where the
    /// scene models those resistances as torques (docs/logs.md); off by default.
    pub controller_integrals_from_effort: bool,
    /// The predictor's inputs (`odom`, `joint_states`) are stale once the last one received is
    /// older than this on the ROS clock (`/clock` under `use_sim_time`) [s] (> 0). An input
    /// never received is not stale: the state is the scene's initial one (and `/diagnostics`
    /// warns that it never came).
    pub timeout: f64,
    /// What the predictor does with stale inputs: `stop` (publish no prediction until they
    /// return) or `warn` (keep predicting from the last state with a WARN, the start covariance
    /// grown by the scene's process noise over the age).
    pub stale_behaviour: StaleBehaviour,
    /// Noise of `joint_states`, for the predictor's start covariance.
    pub joint_noise: JointNoiseParams,
}

/// What the predictor does with stale state inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StaleBehaviour {
    /// Publish nothing until the inputs return.
    Stop,
    /// Keep predicting, with a WARN and a start covariance grown with the age.
    Warn,
}

impl StateParams {
    /// Checks `timeout` and `joint_noise`.
    pub fn validate(&self) -> Result<(), ParamsError> {
        positive("state.timeout", self.timeout)?;
        self.joint_noise.validate()
    }
}

/// `state.joint_noise.*`: standard deviations of the joint states, the diagonal of the start
/// covariance for every 1-DOF joint (the base's comes from the odometry's covariances).
/// Default 0: joint states are taken as exact (encoders resolve far below the base's
/// uncertainty); set them to your encoders' resolution and velocity noise.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointNoiseParams {
    /// σ of every joint position not listed in `joints` [rad or m] (≥ 0).
    pub position: f64,
    /// σ of every joint velocity not listed in `joints` [rad/s or m/s] (≥ 0).
    pub velocity: f64,
    /// Per joint: `name: [σ_position, σ_velocity]` [rad or m, rad/s or m/s] (≥ 0); names are
    /// checked against the model when the node is configured.
    pub joints: std::collections::BTreeMap<String, Vec<f64>>,
}

impl JointNoiseParams {
    /// Checks every value, naming the one that is wrong.
    pub fn validate(&self) -> Result<(), ParamsError> {
        super::nonneg("state.joint_noise.position", self.position)?;
        super::nonneg("state.joint_noise.velocity", self.velocity)?;
        for (name, s) in &self.joints {
            let key = format!("state.joint_noise.joints.{name}");
            if s.len() != 2 {
                return Err(ParamsError::invalid(
                    &key,
                    format!("= {s:?} must be [σ_position, σ_velocity]"),
                ));
            }
            super::nonneg(&key, s[0])?;
            super::nonneg(&key, s[1])?;
        }
        Ok(())
    }

    /// (σ position, σ velocity) of `joint`.
    pub fn of(&self, joint: &str) -> (f64, f64) {
        match self.joints.get(joint) {
            Some(s) if s.len() == 2 => (s[0], s[1]),
            _ => (self.position, self.velocity),
        }
    }
}

impl Default for StateParams {
    fn default() -> Self {
        StateParams {
            joint_states_topic: "joint_states".into(),
            odom_topic: "odom".into(),
            project_to_constraints: true,
            use_measured_effort: true,
            controller_integrals_from_effort: false,
            timeout: 0.5,
            stale_behaviour: StaleBehaviour::Stop,
            joint_noise: JointNoiseParams::default(),
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
    /// Velocity command topic (predictor only): `geometry_msgs/Twist` or `TwistStamped`, see
    /// `type`. The diff drive follows linear.x [m/s] and angular.z [rad/s].
    pub topic: String,
    /// The command topic's message type: `auto` follows whichever of `Twist` and
    /// `TwistStamped` the topic's publishers use (from the DDS graph; `TwistStamped`, Nav2's
    /// and ros2_control's, while nobody publishes), `twist` or `twist_stamped` force one.
    #[serde(rename = "type")]
    pub msg_type: CommandType,
    /// Older spelling of `type: twist_stamped`: true forces `TwistStamped`; false leaves the
    /// choice to `type`.
    pub stamped: bool,
    /// A command older than this is replaced by `fallback` [s].
    pub timeout: f64,
    /// Without a fresh command: `stop` (zero twist, as diff_drive_controller does on timeout),
    /// `hold` (keep the current base twist) or `coast` (wheel controllers off).
    pub fallback: Fallback,
    /// Command every joint that has a position controller in the scene to hold its position at
    /// the start of the prediction.
    pub hold_joints: bool,
}

impl Default for CommandParams {
    fn default() -> Self {
        CommandParams {
            topic: "cmd_vel".into(),
            msg_type: CommandType::Auto,
            stamped: false,
            timeout: 0.5,
            fallback: Fallback::Stop,
            hold_joints: true,
        }
    }
}

/// The message type of a velocity command topic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandMsg {
    /// `geometry_msgs/msg/Twist`.
    Twist,
    /// `geometry_msgs/msg/TwistStamped`.
    TwistStamped,
}

impl CommandMsg {
    /// The DDS type name a publisher of this type announces in discovery.
    pub fn dds_type(self) -> &'static str {
        match self {
            CommandMsg::Twist => "geometry_msgs::msg::dds_::Twist_",
            CommandMsg::TwistStamped => "geometry_msgs::msg::dds_::TwistStamped_",
        }
    }

    /// The ROS type name.
    pub fn ros_type(self) -> &'static str {
        match self {
            CommandMsg::Twist => "geometry_msgs/msg/Twist",
            CommandMsg::TwistStamped => "geometry_msgs/msg/TwistStamped",
        }
    }

    /// The type to subscribe with: the forced one; else the one the topic's publishers use
    /// (`published`: their DDS type names). Where nobody publishes, or both types are
    /// published, the type followed so far stays (`current`), `TwistStamped` at first — what
    /// Nav2 (from Kilted, or with `enable_stamped_cmd_vel`) and ros2_control (from Jazzy)
    /// send.
    pub fn follow(
        forced: Option<CommandMsg>,
        published: &[String],
        current: Option<CommandMsg>,
    ) -> CommandMsg {
        if let Some(f) = forced {
            return f;
        }
        let uses = |t: CommandMsg| published.iter().any(|p| p == t.dds_type());
        match (uses(CommandMsg::Twist), uses(CommandMsg::TwistStamped)) {
            (true, false) => CommandMsg::Twist,
            (false, true) => CommandMsg::TwistStamped,
            _ => current.unwrap_or(CommandMsg::TwistStamped),
        }
    }
}

/// `command.type`: the command topic's message type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CommandType {
    /// Follow whichever type the topic's publishers use.
    Auto,
    /// `geometry_msgs/Twist`.
    Twist,
    /// `geometry_msgs/TwistStamped`.
    TwistStamped,
}

/// What happens without a fresh command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Fallback {
    /// Zero base twist.
    Stop,
    /// The current base twist.
    Hold,
    /// No base command (wheel controllers off).
    Coast,
}

impl CommandParams {
    /// `type` and `stamped` together: `None` = follow the graph, else the forced type.
    pub fn forced_type(&self) -> Result<Option<CommandMsg>, ParamsError> {
        let forced = match self.msg_type {
            CommandType::Auto => None,
            CommandType::Twist => Some(CommandMsg::Twist),
            CommandType::TwistStamped => Some(CommandMsg::TwistStamped),
        };
        match (self.stamped, forced) {
            (false, f) => Ok(f),
            (true, None | Some(CommandMsg::TwistStamped)) => Ok(Some(CommandMsg::TwistStamped)),
            (true, Some(CommandMsg::Twist)) => Err(ParamsError::invalid(
                "command.stamped",
                "= true contradicts command.type = twist",
            )),
        }
    }

    /// Checks `timeout`, and `type` against `stamped`.
    pub fn validate(&self) -> Result<(), ParamsError> {
        positive("command.timeout", self.timeout)?;
        self.forced_type().map(|_| ())
    }
}

/// `diagnostics.*`: the node's status on `/diagnostics`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DiagnosticsParams {
    /// Publication period on the ROS clock [s] (also published at once when the level changes).
    pub period: f64,
    /// An input (`odom`, `joint_states`) older than this on the ROS clock is stale: WARN [s].
    pub input_timeout: f64,
    /// Achieved tick rate below this fraction of `rate` is a missed rate: WARN [-].
    pub min_rate_fraction: f64,
}

impl Default for DiagnosticsParams {
    fn default() -> Self {
        DiagnosticsParams {
            period: 1.0,
            input_timeout: 1.0,
            min_rate_fraction: 0.9,
        }
    }
}

impl DiagnosticsParams {
    /// Checks every value, naming the one that is wrong.
    pub fn validate(&self) -> Result<(), ParamsError> {
        super::work::in_range(
            "diagnostics.period",
            self.period,
            super::work::DIAGNOSTICS_PERIOD,
            "s",
        )?;
        positive("diagnostics.input_timeout", self.input_timeout)?;
        if !(0.0..=1.0).contains(&self.min_rate_fraction) {
            return Err(ParamsError::invalid(
                "diagnostics.min_rate_fraction",
                format!("= {} must be in [0, 1]", self.min_rate_fraction),
            ));
        }
        Ok(())
    }
}
