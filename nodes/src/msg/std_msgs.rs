//! `std_msgs/msg/*`.

use serde::{Deserialize, Serialize};

use super::builtin_interfaces::Time;

/// `std_msgs/msg/Header`: time stamp and coordinate frame of the data.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Time of the data.
    pub stamp: Time,
    /// Frame the data is expressed in (no leading slash by convention).
    pub frame_id: String,
}

/// `std_msgs/msg/String` (named `StringMsg` to keep `String` unshadowed).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StringMsg {
    /// The text.
    pub data: String,
}

/// `std_msgs/msg/ColorRGBA`: each channel in [0, 1] (`float32`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRGBA {
    pub r: f32,
    pub g: f32,
    pub b: f32,
    /// Opacity: 0 is invisible in rviz2.
    pub a: f32,
}

super::ros_messages!("std_msgs": Header, ColorRGBA);

impl ros2_client::Message for StringMsg {}
impl super::RosMessage for StringMsg {
    const PACKAGE: &'static str = "std_msgs";
    const NAME: &'static str = "String";
}
