//! `diagnostic_msgs/msg/*`: the health of each node on `/diagnostics` (rqt_robot_monitor,
//! diagnostic_aggregator).

use serde::{Deserialize, Serialize};

use super::std_msgs::Header;

/// `diagnostic_msgs/msg/KeyValue`: one named value of a status.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct KeyValue {
    /// What the value is (with its unit in brackets).
    pub key: String,
    /// The value as text.
    pub value: String,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`: the state of one component.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// [`DiagnosticStatus::OK`], `WARN`, `ERROR` or `STALE` (`byte` in the .msg).
    pub level: u8,
    /// The component: here the node's fully qualified name.
    pub name: String,
    /// A one-line summary.
    pub message: String,
    /// The hardware this is about: here the robot model's name.
    pub hardware_id: String,
    /// Key–value details.
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// Everything is fine.
    pub const OK: u8 = 0;
    /// Working, with a problem (stale input, missed rate).
    pub const WARN: u8 = 1;
    /// Not working (cannot predict or serve).
    pub const ERROR: u8 = 2;
    /// No recent information.
    pub const STALE: u8 = 3;
}

/// `diagnostic_msgs/msg/DiagnosticArray`: statuses published together.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Stamp (ROS time) of the statuses.
    pub header: Header,
    /// The statuses.
    pub status: Vec<DiagnosticStatus>,
}

super::ros_messages!("diagnostic_msgs": KeyValue, DiagnosticStatus, DiagnosticArray);
