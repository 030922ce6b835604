//! `visualization_msgs/msg/*`: markers for rviz2 (Jazzy/Kilted layout, with the texture,
//! UV and mesh-file fields added in Humble: rviz2 drops a `Marker` without them).

use serde::{Deserialize, Serialize};

use super::builtin_interfaces::Duration;
use super::geometry_msgs::{Point, Pose, Vector3};
use super::sensor_msgs::CompressedImage;
use super::std_msgs::{ColorRGBA, Header};

/// `visualization_msgs/msg/UVCoordinate`: texture coordinates (`float32`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct UVCoordinate {
    pub u: f32,
    pub v: f32,
}

/// `visualization_msgs/msg/MeshFile`: an embedded mesh (unused here: empty).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFile {
    pub filename: String,
    pub data: Vec<u8>,
}

/// `visualization_msgs/msg/Marker`: one shape for rviz2. `points` are in the frame of
/// `header.frame_id` moved by `pose`; units m.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    pub header: Header,
    /// Namespace: with `id`, names the marker (a later one with both replaces it).
    pub ns: String,
    pub id: i32,
    /// [`Marker::ARROW`], [`Marker::LINE_LIST`], …
    #[serde(rename = "type")]
    pub type_: i32,
    /// [`Marker::ADD`], [`Marker::DELETE`], [`Marker::DELETEALL`].
    pub action: i32,
    pub pose: Pose,
    /// Meaning depends on `type_`: an arrow given by two points has shaft diameter x, head
    /// diameter y, head length z; a line list has line width x [m].
    pub scale: Vector3,
    pub color: ColorRGBA,
    /// How long rviz2 shows it without an update; 0 = forever.
    pub lifetime: Duration,
    pub frame_locked: bool,
    pub points: Vec<Point>,
    pub colors: Vec<ColorRGBA>,
    pub texture_resource: String,
    pub texture: CompressedImage,
    pub uv_coordinates: Vec<UVCoordinate>,
    pub text: String,
    pub mesh_resource: String,
    pub mesh_file: MeshFile,
    pub mesh_use_embedded_materials: bool,
}

impl Marker {
    /// An arrow (from `points[0]` to `points[1]` when two points are given).
    pub const ARROW: i32 = 0;
    /// Line segments between consecutive pairs of `points`.
    pub const LINE_LIST: i32 = 5;
    /// Add or replace.
    pub const ADD: i32 = 0;
    /// Remove the marker named by `ns` and `id`.
    pub const DELETE: i32 = 2;
    /// Remove every marker of the display.
    pub const DELETEALL: i32 = 3;
}

/// `visualization_msgs/msg/MarkerArray`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerArray {
    pub markers: Vec<Marker>,
}

super::ros_messages!("visualization_msgs": UVCoordinate, MeshFile, Marker, MarkerArray);
