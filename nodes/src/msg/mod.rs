//! ROS 2 message and service types, as serde structs for ros2-client.
//!
//! Each struct lists the fields of its `.msg` in the same order with the same
//! names and CDR types (`float64` → `f64`, `uint32` → `u32`, `string` →
//! `String`, `T[]` → `Vec<T>`, `float64[36]` → `[f64; 36]` via
//! `serde-big-array`). The CDR layout is checked byte for byte against rclpy in
//! `nodes/tests/it/golden_messages.rs`.
//!
//! One module per ROS package; module paths mirror the ROS names
//! (`geometry_msgs::Twist` is `geometry_msgs/msg/Twist`). The services of
//! `constraint_dynamics_msgs` are in [`constraint_dynamics_msgs::srv`].

use ros2_client::{Message, MessageTypeName, ServiceTypeName};

pub mod builtin_interfaces;
pub mod constraint_dynamics_msgs;
pub mod diagnostic_msgs;
pub mod geometry_msgs;
pub mod lifecycle_msgs;
pub mod nav_msgs;
pub mod rcl_interfaces;
pub mod rosgraph_msgs;
pub mod sensor_msgs;
pub mod std_msgs;
pub mod std_srvs;
pub mod visualization_msgs;

/// A message type that knows its ROS name (`package/msg/Name`).
pub trait RosMessage: Message {
    /// ROS package, e.g. `"nav_msgs"`.
    const PACKAGE: &'static str;
    /// Type name within the package, e.g. `"Odometry"`.
    const NAME: &'static str;

    /// The name ros2-client needs to create a topic of this type.
    fn type_name() -> MessageTypeName {
        MessageTypeName::new(Self::PACKAGE, Self::NAME)
    }
}

/// A service type that knows its ROS name and its request/response types.
pub trait RosService {
    /// `Name_Request` of the `.srv`.
    type Request: Message + Clone + 'static;
    /// `Name_Response` of the `.srv`.
    type Response: Message + 'static;
    /// ROS package, e.g. `"constraint_dynamics_msgs"`.
    const PACKAGE: &'static str;
    /// Service name within the package, e.g. `"GetConstraintForces"`.
    const NAME: &'static str;

    /// The name ros2-client needs to create a client or server of this type.
    fn type_name() -> ServiceTypeName {
        ServiceTypeName::new(Self::PACKAGE, Self::NAME)
    }
}

/// Implements [`Message`] and [`RosMessage`] for message structs of one package.
macro_rules! ros_messages {
    ($package:literal: $($ty:ident),+ $(,)?) => {
        $(
            impl ros2_client::Message for $ty {}
            impl $crate::msg::RosMessage for $ty {
                const PACKAGE: &'static str = $package;
                const NAME: &'static str = stringify!($ty);
            }
        )+
    };
}
pub(crate) use ros_messages;
