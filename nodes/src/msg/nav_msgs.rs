//! `nav_msgs/msg/*`.

use serde::{Deserialize, Serialize};

use super::geometry_msgs::{PoseStamped, PoseWithCovariance, TwistWithCovariance};
use super::std_msgs::Header;

/// `nav_msgs/msg/Odometry`: pose in `header.frame_id` (e.g. `odom`), twist in
/// `child_frame_id` (e.g. `base_link`), REP-105.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    pub header: Header,
    pub child_frame_id: String,
    pub pose: PoseWithCovariance,
    pub twist: TwistWithCovariance,
}

/// `nav_msgs/msg/Path`: a sequence of poses.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Path {
    pub header: Header,
    pub poses: Vec<PoseStamped>,
}

super::ros_messages!("nav_msgs": Odometry, Path);
