//! `sensor_msgs/msg/*`.

use serde::{Deserialize, Serialize};

use super::std_msgs::Header;

/// `sensor_msgs/msg/JointState`: per named joint, position [m or rad],
/// velocity [m/s or rad/s] and effort [N or N·m]; each array is either empty
/// or as long as `name`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

/// `sensor_msgs/msg/CompressedImage` (here only as the empty `texture` of a marker).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    pub header: Header,
    /// `jpeg`, `png`, … ("" when unused).
    pub format: String,
    pub data: Vec<u8>,
}

super::ros_messages!("sensor_msgs": JointState, CompressedImage);
