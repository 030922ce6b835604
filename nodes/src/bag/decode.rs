//! One recorded message: its CDR bytes (a 4-byte encapsulation header, then the payload) into
//! the message structs of [`crate::msg`], and those into the core's replay samples.

use byteorder::{BigEndian, LittleEndian};
use constraint_dynamics::model::{BasePose, BaseTwist};
use constraint_dynamics::replay::{JointStates, Odometry as OdometrySample};
use serde::de::DeserializeOwned;

use crate::msg::geometry_msgs::{Twist, TwistStamped};
use crate::msg::nav_msgs::Odometry;
use crate::msg::sensor_msgs::JointState;

/// A message type the reader takes, by its rosbag2 schema name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `nav_msgs/msg/Odometry`.
    Odometry,
    /// `sensor_msgs/msg/JointState`.
    JointState,
    /// `geometry_msgs/msg/Twist` (no stamp: timed by the bag's log time).
    Twist,
    /// `geometry_msgs/msg/TwistStamped`.
    TwistStamped,
}

impl Kind {
    /// The schema name rosbag2 writes for it.
    pub fn schema(self) -> &'static str {
        match self {
            Kind::Odometry => "nav_msgs/msg/Odometry",
            Kind::JointState => "sensor_msgs/msg/JointState",
            Kind::Twist => "geometry_msgs/msg/Twist",
            Kind::TwistStamped => "geometry_msgs/msg/TwistStamped",
        }
    }
}

/// A decoded message as a replay sample, with its time [ns] (header stamp, or for a Twist the
/// log time given).
pub enum Decoded {
    /// An odometry sample (boxed: its covariances are 600 bytes).
    Odometry(i64, Box<OdometrySample>),
    /// A joint-state sample.
    JointStates(i64, JointStates),
    /// A base command (v, ω).
    Command(i64, [f64; 2]),
}

/// `T` from CDR bytes with their encapsulation header (plain CDR, either byte order).
pub fn cdr<T: DeserializeOwned>(data: &[u8]) -> Result<T, String> {
    let (header, payload) = match data {
        [a, b, _, _, rest @ ..] => ([*a, *b], rest),
        _ => return Err(format!("{} bytes, shorter than the CDR header", data.len())),
    };
    let decoded = match header {
        [0, 1] => cdr_encoding::from_bytes::<T, LittleEndian>(payload),
        [0, 0] => cdr_encoding::from_bytes::<T, BigEndian>(payload),
        h => return Err(format!("CDR encapsulation {h:02x?} is not plain CDR")),
    };
    decoded.map(|(t, _)| t).map_err(|e| format!("CDR: {e}"))
}

/// Decodes one message of kind `kind` logged at `log_time` [ns].
pub fn decode(kind: Kind, data: &[u8], log_time: i64) -> Result<Decoded, String> {
    Ok(match kind {
        Kind::Odometry => {
            let od: Odometry = cdr(data)?;
            Decoded::Odometry(od.header.stamp.to_nanos(), Box::new(odometry_sample(&od)))
        }
        Kind::JointState => {
            let js: JointState = cdr(data)?;
            let t = js.header.stamp.to_nanos();
            Decoded::JointStates(
                t,
                JointStates {
                    name: js.name,
                    position: js.position,
                    velocity: js.velocity,
                    effort: js.effort,
                },
            )
        }
        Kind::Twist => {
            let tw: Twist = cdr(data)?;
            Decoded::Command(log_time, [tw.linear.x, tw.angular.z])
        }
        Kind::TwistStamped => {
            let ts: TwistStamped = cdr(data)?;
            let t = ts.header.stamp.to_nanos();
            Decoded::Command(t, [ts.twist.linear.x, ts.twist.angular.z])
        }
    })
}

/// The replay sample of a `nav_msgs/Odometry` (pose in the header frame, twist in the child
/// frame; covariances as REP-103 lays them out, which is the core's layout).
pub fn odometry_sample(od: &Odometry) -> OdometrySample {
    let p = &od.pose.pose;
    let t = &od.twist.twist;
    let o = &p.orientation;
    OdometrySample {
        pose: BasePose {
            position: [p.position.x, p.position.y, p.position.z],
            orientation_xyzw: [o.x, o.y, o.z, o.w],
        },
        twist: BaseTwist {
            linear: [t.linear.x, t.linear.y, t.linear.z],
            angular: [t.angular.x, t.angular.y, t.angular.z],
        },
        pose_covariance: od.pose.covariance,
        twist_covariance: od.twist.covariance,
    }
}
