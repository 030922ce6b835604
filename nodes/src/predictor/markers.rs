//! What rviz2 shows of a prediction, as plain functions (data in, messages out):
//! - an arrow per constraint force at its point of application, length = force × scale,
//!   coloured by the contact judgement (contacts green while they hold, red where they slip or
//!   lift off; other constraints blue);
//! - the robot's footprint along the predicted path, one outline every `footprint_period`;
//! - each constraint's wrench as a `WrenchStamped` in its own frame (rviz2's Wrench display).
//!
//! All arrows are drawn in the fixed (odom) frame: a force given in a frame's axes is rotated
//! into world axes with that frame's rotation at the same state, so rviz2 needs no TF of the
//! robot's links to place them. Nothing non-finite is emitted: a force or pose with a NaN or an
//! infinity is left out.

use constraint_dynamics::constraints::{ConstraintForce, ContactState};

use crate::msg::builtin_interfaces::{Duration, Time};
use crate::msg::geometry_msgs::{Point, Vector3, Wrench, WrenchStamped};
use crate::msg::nav_msgs::Path;
use crate::msg::std_msgs::{ColorRGBA, Header};
use crate::msg::visualization_msgs::Marker;

/// A rotation matrix (row-major): frame axes → world axes.
pub type Rotation = [[f64; 3]; 3];

/// How the markers look.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerStyle {
    /// Arrow length per newton [m/N].
    pub force_scale: f64,
    /// Arrow shaft diameter [m] (head: twice as wide, three times as long).
    pub arrow_width: f64,
    /// How long rviz2 keeps a marker without an update [s]: a few prediction periods, so
    /// markers vanish when the node stops predicting.
    pub lifetime: f64,
    /// Footprint outline width [m].
    pub line_width: f64,
}

/// Namespace of the force arrows (ids: the constraint's index).
pub const FORCES_NS: &str = "constraint_forces";
/// Namespace of the footprint outlines (one marker, id 0).
pub const FOOTPRINT_NS: &str = "predicted_footprint";

/// Contact that holds (grips and pushes).
pub const GRIP: ColorRGBA = rgba(0.1, 0.8, 0.1);
/// Contact that breaks (slips or lifts off).
pub const SLIP: ColorRGBA = rgba(1.0, 0.1, 0.1);
/// Any other constraint.
pub const OTHER: ColorRGBA = rgba(0.2, 0.4, 1.0);
/// Footprint outlines.
pub const FOOTPRINT: ColorRGBA = rgba(1.0, 0.6, 0.1);

const fn rgba(r: f32, g: f32, b: f32) -> ColorRGBA {
    ColorRGBA { r, g, b, a: 1.0 }
}

fn finite(a: &[f64]) -> bool {
    a.iter().all(|x| x.is_finite())
}

fn mul(r: &Rotation, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2])
}

fn mul_transpose(r: &Rotation, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| r[0][i] * v[0] + r[1][i] * v[1] + r[2][i] * v[2])
}

fn point(a: [f64; 3]) -> Point {
    Point {
        x: a[0],
        y: a[1],
        z: a[2],
    }
}

fn vector(a: [f64; 3]) -> Vector3 {
    Vector3 {
        x: a[0],
        y: a[1],
        z: a[2],
    }
}

/// The force of `f` in world axes [N]: as is for world axes, rotated by its axes frame's
/// rotation otherwise (`None` when that rotation is unknown).
fn world_force(
    f: &ConstraintForce,
    rotation: &dyn Fn(&str) -> Option<Rotation>,
) -> Option<[f64; 3]> {
    if f.axes == "world" {
        Some(f.force)
    } else {
        rotation(&f.axes).map(|r| mul(&r, f.force))
    }
}

/// One arrow per constraint with a point of application (couplings have none), from that
/// point along the force on the robot, in `header.frame_id` (the fixed frame); `contacts[k]`
/// is constraint k's contact judged at the forces (`None`: not a contact).
pub fn force_markers(
    forces: &[ConstraintForce],
    contacts: &[Option<ContactState>],
    rotation: &dyn Fn(&str) -> Option<Rotation>,
    header: &Header,
    style: &MarkerStyle,
) -> Vec<Marker> {
    let mut out = Vec::new();
    for (k, f) in forces.iter().enumerate() {
        if f.frame_origin_world.is_none() {
            continue; // a coupling: a generalized force, nowhere in space
        }
        let Some(force) = world_force(f, rotation) else {
            continue;
        };
        let p = f.point_world;
        let tip = [0, 1, 2].map(|i| p[i] + style.force_scale * force[i]);
        if !finite(&tip) || !finite(&p) {
            continue;
        }
        let color = match contacts.get(k).copied().flatten() {
            Some(s) if s.breaks.is_some() => SLIP,
            Some(_) => GRIP,
            None => OTHER,
        };
        out.push(Marker {
            header: header.clone(),
            ns: FORCES_NS.into(),
            id: k as i32,
            type_: Marker::ARROW,
            action: Marker::ADD,
            scale: vector([
                style.arrow_width,
                2.0 * style.arrow_width,
                3.0 * style.arrow_width,
            ]),
            color,
            lifetime: Duration::from_secs_f64(style.lifetime),
            points: vec![point(p), point(tip)],
            text: f.name.clone(),
            ..Default::default()
        });
    }
    out
}

/// Poses of `path` one `period` [s] apart (by their stamps), the first and the last always.
fn outline_poses(path: &Path, period: f64) -> Vec<usize> {
    let n = path.poses.len();
    let mut picked: Vec<usize> = Vec::new();
    let t = |i: usize| path.poses[i].header.stamp.to_secs();
    for i in 0..n {
        let due = match picked.last() {
            None => true,
            // A nanosecond of slack: stamps are rounded to whole nanoseconds.
            Some(&j) => t(i) - t(j) >= period - 1e-9,
        };
        if due || i + 1 == n {
            picked.push(i);
        }
    }
    picked
}

/// The footprint polygon `footprint` ([x, y] vertices in the base frame [m]) at poses of the
/// predicted `path` one `period` apart, as one LINE_LIST marker in the path's frame.
pub fn footprint_marker(
    path: &Path,
    footprint: &[[f64; 2]],
    period: f64,
    stamp: Time,
    style: &MarkerStyle,
) -> Marker {
    let mut points = Vec::new();
    for i in outline_poses(path, period) {
        let pose = &path.poses[i].pose;
        let q = &pose.orientation;
        let r = rotation_of([q.x, q.y, q.z, q.w]);
        let o = [pose.position.x, pose.position.y, pose.position.z];
        let corners: Vec<[f64; 3]> = footprint
            .iter()
            .map(|c| {
                let w = mul(&r, [c[0], c[1], 0.0]);
                [o[0] + w[0], o[1] + w[1], o[2] + w[2]]
            })
            .collect();
        if corners.iter().any(|c| !finite(c)) {
            continue;
        }
        for k in 0..corners.len() {
            points.push(point(corners[k]));
            points.push(point(corners[(k + 1) % corners.len()]));
        }
    }
    Marker {
        header: Header {
            stamp,
            frame_id: path.header.frame_id.clone(),
        },
        ns: FOOTPRINT_NS.into(),
        id: 0,
        type_: Marker::LINE_LIST,
        action: Marker::ADD,
        pose: Default::default(),
        scale: vector([style.line_width, 0.0, 0.0]),
        color: FOOTPRINT,
        lifetime: Duration::from_secs_f64(style.lifetime),
        points,
        ..Default::default()
    }
}

/// The rotation of a unit quaternion (x, y, z, w); a non-unit one is normalised, a zero or
/// non-finite one gives NaNs (left out by the callers).
pub fn rotation_of(q: [f64; 4]) -> Rotation {
    let n = q.iter().map(|a| a * a).sum::<f64>().sqrt();
    let [x, y, z, w] = q.map(|a| a / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Each constraint's wrench on the robot as a `WrenchStamped` in its own frame: about the
/// frame's origin (`ConstraintForce::wrench_at_frame_origin`), in the frame's axes. A
/// constraint on the world frame is reported in `world_frame`. Couplings and constraints whose
/// frame rotation is unknown are left out. Returns (constraint name, message).
pub fn constraint_wrenches(
    forces: &[ConstraintForce],
    rotation: &dyn Fn(&str) -> Option<Rotation>,
    world_frame: &str,
    stamp: Time,
) -> Vec<(String, WrenchStamped)> {
    let mut out = Vec::new();
    for f in forces {
        if f.frame_origin_world.is_none() {
            continue;
        }
        let w = f.wrench_at_frame_origin();
        let (force, torque) = ([w.lin.x, w.lin.y, w.lin.z], [w.ang.x, w.ang.y, w.ang.z]);
        let (frame_id, force, torque) = if f.axes == f.frame {
            (f.frame.clone(), force, torque)
        } else if f.axes == "world" && f.frame == "world" {
            (world_frame.to_string(), force, torque)
        } else if f.axes == "world" {
            let Some(r) = rotation(&f.frame) else {
                continue;
            };
            (
                f.frame.clone(),
                mul_transpose(&r, force),
                mul_transpose(&r, torque),
            )
        } else {
            continue;
        };
        if !finite(&force) || !finite(&torque) {
            continue;
        }
        let frame_id = if frame_id == "world" {
            world_frame.to_string()
        } else {
            frame_id
        };
        out.push((
            f.name.clone(),
            WrenchStamped {
                header: Header { stamp, frame_id },
                wrench: Wrench {
                    force: vector(force),
                    torque: vector(torque),
                },
            },
        ));
    }
    out
}

/// A constraint name as one token of a ROS topic name (`~/wrench/<token>`): letters, digits and
/// `_` kept, anything else `_`, and `_` in front of a leading digit.
pub fn topic_token(name: &str) -> String {
    let mut t: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if t.is_empty() || t.starts_with(|c: char| c.is_ascii_digit()) {
        t.insert(0, '_');
    }
    t
}

#[cfg(test)]
mod tests;
