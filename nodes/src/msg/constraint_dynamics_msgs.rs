//! `constraint_dynamics_msgs/msg/*` and `/srv/*`: this project's interfaces.
//!
//! The ROS definitions (with the meaning and unit of every field) are in
//! `interfaces/constraint_dynamics_msgs/`; these structs follow them field for
//! field.

use serde::{Deserialize, Serialize};

use super::geometry_msgs::Wrench;
use super::std_msgs::Header;

/// `constraint_dynamics_msgs/msg/ConstraintForce`: the force one constraint
/// exerts, BY the environment ON the robot.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ConstraintForce {
    /// Constraint name, as in the node's constraint parameters.
    pub name: String,
    /// `point`, `weld`, `distance`, `coupling`, `rolling` or `no_side_slip`.
    pub kind: String,
    /// Frame at whose origin the wrench acts.
    pub frame_id: String,
    /// Frame whose axes express the wrench.
    pub axes_frame_id: String,
    /// The constraint force [N, N·m].
    pub wrench: Wrench,
    /// Raw multipliers λ, one per row.
    pub multipliers: Vec<f64>,
    /// Row names, as long as `multipliers`.
    pub row_names: Vec<String>,
    /// Position-level residual per row [m or rad] (empty if non-holonomic).
    pub position_residual: Vec<f64>,
    /// Velocity-level residual J·v per row [m/s or rad/s].
    pub velocity_residual: Vec<f64>,
    /// Rolling only: normal force magnitude [N], else 0.
    pub normal_force: f64,
    /// Rolling only: tangential force magnitude [N], else 0.
    pub tangential_force: f64,
    /// Rolling only: `tangential_force > μ · normal_force`.
    pub slipping: bool,
}

/// `constraint_dynamics_msgs/msg/ConstraintForces`: all constraint forces at one state.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ConstraintForces {
    /// Stamp of the state; frame_id the world frame.
    pub header: Header,
    /// One per constraint, in the node's constraint order.
    pub constraints: Vec<ConstraintForce>,
    /// Names of the velocity coordinates (nv).
    pub v_names: Vec<String>,
    /// Jᵀλ per velocity coordinate [N or N·m].
    pub generalized_force: Vec<f64>,
    /// Number of dependent constraint rows (0 if J has full row rank).
    pub rank_deficiency: u32,
}

/// `constraint_dynamics_msgs/msg/AccelerationLimit`: one limit of the base's acceleration
/// envelope.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AccelerationLimit {
    /// [`AccelerationLimit::BOUNDED`], [`AccelerationLimit::UNBOUNDED`] or
    /// [`AccelerationLimit::INFEASIBLE`].
    pub status: u8,
    /// The signed maximum when bounded [m/s² or rad/s²]; 0 otherwise.
    pub max: f64,
    /// `effort`, `friction`, `lift_off` or `bound`, one per binding limit.
    pub binding_kinds: Vec<String>,
    /// The joint, constraint or coordinate each binding limit names.
    pub binding_names: Vec<String>,
}

impl AccelerationLimit {
    /// `max` holds the limit.
    pub const BOUNDED: u8 = 0;
    /// Nothing limits this direction.
    pub const UNBOUNDED: u8 = 1;
    /// No acceleration meets every limit with the other base coordinate held.
    pub const INFEASIBLE: u8 = 2;
}

/// `constraint_dynamics_msgs/msg/AccelerationLimits`: the base's acceleration envelope at one
/// state (derivatives of the base twist in the base frame).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AccelerationLimits {
    /// Stamp of the state; frame_id the base frame.
    pub header: Header,
    /// Largest forward acceleration a_x [m/s²], yaw acceleration held at 0.
    pub forward_acceleration: AccelerationLimit,
    /// Largest forward deceleration −a_x [m/s²], yaw acceleration held at 0.
    pub forward_deceleration: AccelerationLimit,
    /// Largest yaw acceleration to the left +α_z [rad/s²], forward acceleration held at 0.
    pub yaw_acceleration_left: AccelerationLimit,
    /// Largest yaw acceleration to the right −α_z [rad/s²], forward acceleration held at 0.
    pub yaw_acceleration_right: AccelerationLimit,
    /// Kinds of the limits not checked (`effort`, `friction`, `lift_off`).
    pub unchecked_kinds: Vec<String>,
    /// What each unchecked limit names, as long as `unchecked_kinds`.
    pub unchecked_names: Vec<String>,
}

super::ros_messages!(
    "constraint_dynamics_msgs": ConstraintForce,
    ConstraintForces,
    AccelerationLimit,
    AccelerationLimits
);

/// `constraint_dynamics_msgs/srv/*`.
pub mod srv {
    use serde::{Deserialize, Serialize};

    use super::ConstraintForces;
    use crate::msg::RosService;
    use crate::msg::geometry_msgs::{Inertia, Pose, Twist};
    use crate::msg::nav_msgs::Path;
    use crate::msg::std_msgs::Header;

    /// Implements [`RosService`] for a marker type and [`ros2_client::Message`]
    /// for its request and response.
    macro_rules! ros_service {
        ($srv:ident, $req:ident, $resp:ident) => {
            #[doc = concat!("Marker for the `constraint_dynamics_msgs/srv/", stringify!($srv), "` service.")]
            #[derive(Clone, Copy, Debug)]
            pub struct $srv;
            impl RosService for $srv {
                type Request = $req;
                type Response = $resp;
                const PACKAGE: &'static str = "constraint_dynamics_msgs";
                const NAME: &'static str = stringify!($srv);
            }
            impl ros2_client::Message for $req {}
            impl ros2_client::Message for $resp {}
        };
    }

    /// Request of `GetConstraintForces`. Empty name lists mean the node's coordinate order.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct GetConstraintForcesRequest {
        pub use_latest_state: bool,
        pub q_names: Vec<String>,
        /// Configuration [m, rad, quaternion components].
        pub q: Vec<f64>,
        pub v_names: Vec<String>,
        /// Velocity [m/s, rad/s].
        pub v: Vec<f64>,
        /// Actuator generalized forces in v order [N, N·m]; empty = zero.
        pub tau: Vec<f64>,
    }

    /// Response of `GetConstraintForces`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct GetConstraintForcesResponse {
        pub success: bool,
        pub message: String,
        pub forces: ConstraintForces,
        /// Generalized acceleration in `forces.v_names` order [m/s², rad/s²].
        pub qdd: Vec<f64>,
    }

    ros_service!(
        GetConstraintForces,
        GetConstraintForcesRequest,
        GetConstraintForcesResponse
    );

    /// Request of `ProjectVelocity`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct ProjectVelocityRequest {
        pub use_latest_state: bool,
        pub q: Vec<f64>,
        pub v_names: Vec<String>,
        pub v_des: Vec<f64>,
        pub use_twist: bool,
        /// Desired base twist in the base frame [m/s, rad/s].
        pub base_twist: Twist,
        pub joint_names: Vec<String>,
        pub joint_velocities: Vec<f64>,
        pub bound_names: Vec<String>,
        pub lower: Vec<f64>,
        pub upper: Vec<f64>,
        /// If > 0, bound |v − v_current| ≤ a_max · accel_limit_dt [s].
        pub accel_limit_dt: f64,
        /// Control period [s]: > 0 asks for a velocity reachable within it under the robot's
        /// efforts, friction cones and contacts (the dynamic projection); 0 = kinematic.
        pub period: f64,
        /// Current velocity (nv, the node's order) when `use_latest_state` is false; empty =
        /// the node's latest [m/s, rad/s].
        pub v_current: Vec<f64>,
    }

    /// Response of `ProjectVelocity`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct ProjectVelocityResponse {
        pub success: bool,
        pub message: String,
        /// `optimal`, `infeasible` or `error`.
        pub status: String,
        pub v_names: Vec<String>,
        pub v: Vec<f64>,
        pub base_twist: Twist,
        pub joint_names: Vec<String>,
        pub joint_velocities: Vec<f64>,
        pub constraint_names: Vec<String>,
        /// Impulse per constraint row [N·s, N·m·s].
        pub impulses: Vec<f64>,
        pub active_bounds: Vec<String>,
        pub conflicting: Vec<String>,
        /// What binds the answer: `effort` (joint), `friction` / `lift_off` (constraint),
        /// `bound` (coordinate); parallel to `binding_names`. Empty with period 0.
        pub binding_kinds: Vec<String>,
        pub binding_names: Vec<String>,
        /// Limits the dynamics cannot check (same kinds), parallel to `unchecked_names`.
        pub unchecked_kinds: Vec<String>,
        pub unchecked_names: Vec<String>,
    }

    ros_service!(
        ProjectVelocity,
        ProjectVelocityRequest,
        ProjectVelocityResponse
    );

    /// Request of `Predict`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct PredictRequest {
        pub use_latest_state: bool,
        pub q: Vec<f64>,
        pub v: Vec<f64>,
        /// Base twists, each held for `command_period`; the last held to `horizon`.
        pub commands: Vec<Twist>,
        /// [s]
        pub command_period: f64,
        /// [s]
        pub horizon: f64,
        pub with_forces: bool,
        pub with_covariance: bool,
        /// 2nv × 2nv row-major, [δq; δv]; empty = the node's (odometry, joint noise).
        pub start_covariance: Vec<f64>,
    }

    /// Response of `Predict`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct PredictResponse {
        pub success: bool,
        pub message: String,
        pub path: Path,
        /// Time of each pose relative to the start [s].
        pub times: Vec<f64>,
        pub forces: Vec<ConstraintForces>,
        /// Error estimate of the base's position at the horizon [m] (integration estimate +
        /// holonomic residual).
        pub position_error_estimate: f64,
        /// n = 2nv (with `with_covariance`).
        pub covariance_dimension: u32,
        /// Each sample's n × n covariance, row-major, concatenated in `times` order.
        pub covariances: Vec<f64>,
        /// Error estimate of the base's orientation at the horizon [rad] (integration estimate
        /// + holonomic residual).
        pub orientation_error_estimate: f64,
        /// Integration error estimate of the revolute joints' angles at the horizon [rad]; 0
        /// without such joints or without the estimate.
        pub joint_error_estimate_rad: f64,
        /// Integration error estimate of the prismatic joints' displacements at the horizon
        /// [m]; 0 without such joints or without the estimate.
        pub joint_error_estimate_m: f64,
    }

    ros_service!(Predict, PredictRequest, PredictResponse);

    /// Request of `Rollouts`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct RolloutsRequest {
        pub use_latest_state: bool,
        pub q: Vec<f64>,
        pub v: Vec<f64>,
        /// N sequences of `sequence_length` base twists, concatenated.
        pub commands: Vec<Twist>,
        pub sequence_length: u32,
        /// How long each command is held; the sampling period [s].
        pub step: f64,
        pub with_forces: bool,
    }

    /// Response of `Rollouts`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct RolloutsResponse {
        pub success: bool,
        pub message: String,
        /// The odom frame and the start time.
        pub header: Header,
        /// Base pose after each step, N × sequence_length, sequence after sequence.
        pub poses: Vec<Pose>,
        /// Base twist in the base frame after each step, as `poses`.
        pub twists: Vec<Twist>,
        /// Constraint forces after each step, as `poses` (with `with_forces`).
        pub forces: Vec<ConstraintForces>,
    }

    ros_service!(Rollouts, RolloutsRequest, RolloutsResponse);

    /// Request of `SetPayload`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct SetPayloadRequest {
        /// Frame (URDF link) carrying the payload.
        pub frame: String,
        /// Mass [kg], centre of mass [m] in `frame`, inertia about it [kg·m²].
        pub inertia: Inertia,
    }

    /// Response of `SetPayload`.
    #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
    pub struct SetPayloadResponse {
        pub success: bool,
        pub message: String,
    }

    ros_service!(SetPayload, SetPayloadRequest, SetPayloadResponse);
}
