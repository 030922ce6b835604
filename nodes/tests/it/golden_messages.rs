//! The Rust message types produce the same CDR bytes as rclpy (rmw_fastrtps_cpp).
//!
//! `tests/golden/*.bin` were written by `tools/ros2/make_golden.py` with
//! `rclpy.serialization.serialize_message` (4-byte encapsulation header + CDR
//! body); `tests/golden/values.json` holds the field values of each message. For
//! every case this test
//! 1. builds the Rust struct from the JSON values (so field names must match the .msg),
//! 2. serializes it with the serializer ros2-client's publishers use
//!    (RustDDS `CDRSerializerAdapter`, little endian, header `00 01 00 00`) and
//!    compares with the golden bytes (whose alignment gaps make_golden.py set
//!    to zero, as RustDDS writes them, after checking that rclpy still decodes
//!    them to the same message),
//! 3. deserializes the golden bytes the way ros2-client's subscriptions do and
//!    compares with the struct, and
//! 4. converts the struct back to JSON and compares with the values (no field
//!    missing or extra).
//!
//! No DDS participant is opened. Regenerate the golden files only when a message
//! definition changes (see docs/ros2.md).

use std::path::PathBuf;

use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::srv::*;
use constraint_dynamics_nodes::msg::constraint_dynamics_msgs::{
    AccelerationLimit, AccelerationLimits, ConstraintForce, ConstraintForces,
};
use constraint_dynamics_nodes::msg::geometry_msgs::*;
use constraint_dynamics_nodes::msg::lifecycle_msgs::{
    ChangeState, GetAvailableStates, GetAvailableTransitions, GetState, State, TransitionEvent,
};
use constraint_dynamics_nodes::msg::nav_msgs::{Odometry, Path};
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::msg::std_msgs::{Header, StringMsg};
use constraint_dynamics_nodes::msg::std_srvs::Trigger;
use constraint_dynamics_nodes::msg::visualization_msgs::{Marker, MarkerArray};
use constraint_dynamics_nodes::msg::{RosMessage, RosService};
use ros2_client::dds::rustdds::RepresentationIdentifier;
use ros2_client::dds::rustdds::no_key::SerializerAdapter;
use ros2_client::dds::rustdds::serialization::{
    CDRSerializerAdapter, deserialize_from_cdr_with_rep_id,
};
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

fn golden_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn values() -> serde_json::Map<String, Value> {
    let text = std::fs::read_to_string(golden_dir().join("values.json"))
        .expect("tests/golden/values.json");
    match serde_json::from_str(&text).expect("values.json is JSON") {
        Value::Object(m) => m,
        _ => panic!("values.json is not an object"),
    }
}

/// Bytes as a ros2-client publisher puts them in the RTPS payload:
/// representation identifier CDR_LE, options 0, then the CDR body.
fn rust_bytes<T: Serialize>(msg: &T) -> Vec<u8> {
    let mut out = RepresentationIdentifier::CDR_LE.to_bytes().to_vec();
    out.extend_from_slice(&[0, 0]);
    out.extend_from_slice(&CDRSerializerAdapter::<T>::to_bytes(msg).expect("serialize"));
    out
}

/// Decodes payload bytes as a ros2-client subscription does.
fn rust_decode<T: DeserializeOwned>(bytes: &[u8]) -> (T, usize) {
    let rep = RepresentationIdentifier::from_bytes(&bytes[0..2]).expect("rep id");
    deserialize_from_cdr_with_rep_id::<T>(&bytes[4..], rep).expect("deserialize")
}

fn first_difference(a: &[u8], b: &[u8]) -> String {
    let i = a
        .iter()
        .zip(b)
        .position(|(x, y)| x != y)
        .unwrap_or(a.len().min(b.len()));
    let lo = i.saturating_sub(8);
    format!(
        "lengths rust {} rclpy {}; first difference at byte {i}: rust {:02x?} rclpy {:02x?}",
        a.len(),
        b.len(),
        &a[lo..(i + 8).min(a.len())],
        &b[lo..(i + 8).min(b.len())]
    )
}

/// Runs the four checks for one case; returns a description of a failure.
fn check<T>(case: &str, ros_type: &str, all: &serde_json::Map<String, Value>) -> Result<(), String>
where
    T: Serialize + DeserializeOwned + PartialEq + std::fmt::Debug,
{
    let entry = all
        .get(case)
        .ok_or_else(|| format!("{case}: not in values.json"))?;
    if entry["type"] != ros_type {
        return Err(format!(
            "{case}: values.json says type {}, test expects {ros_type}",
            entry["type"]
        ));
    }
    let value = &entry["value"];
    let msg: T =
        serde_json::from_value(value.clone()).map_err(|e| format!("{case}: JSON → Rust: {e}"))?;

    let golden = std::fs::read(golden_dir().join(format!("{case}.bin")))
        .map_err(|e| format!("{case}.bin: {e}"))?;
    if golden.len() < 4 || golden[0..4] != [0x00, 0x01, 0x00, 0x00] {
        return Err(format!(
            "{case}: golden header {:02x?} is not CDR_LE 00 01 00 00",
            &golden[..4.min(golden.len())]
        ));
    }
    // rclpy's buffer may end with up to 7 bytes more than the CDR body needs
    // (Fast-CDR sizes an empty float64[] as if it were followed by alignment);
    // make_golden.py zeroed them, and every reader ignores them.
    let ours = rust_bytes(&msg);
    let trailing = entry["trailing_bytes"].as_u64().unwrap_or(0) as usize;
    if ours.len() + trailing != golden.len() || ours[..] != golden[..ours.len()] {
        return Err(format!(
            "{case}: bytes differ: {}",
            first_difference(&ours, &golden)
        ));
    }
    if golden[ours.len()..].iter().any(|&b| b != 0) || trailing > 7 {
        return Err(format!(
            "{case}: unexpected trailing bytes {:02x?}",
            &golden[ours.len()..]
        ));
    }

    let (decoded, consumed): (T, usize) = rust_decode(&golden);
    if decoded != msg {
        return Err(format!(
            "{case}: decoding the golden bytes gives\n{decoded:?}\nexpected\n{msg:?}"
        ));
    }
    if consumed != ours.len() - 4 {
        return Err(format!(
            "{case}: decoding consumed {consumed} of {} body bytes",
            ours.len() - 4
        ));
    }

    let back = serde_json::to_value(&msg).map_err(|e| format!("{case}: Rust → JSON: {e}"))?;
    if &back != value {
        return Err(format!(
            "{case}: fields differ from the .msg:\nrust  {back}\nrclpy {value}"
        ));
    }
    Ok(())
}

fn msg_type<T: RosMessage>() -> String {
    format!("{}/msg/{}", T::PACKAGE, T::NAME)
}

fn srv_types<S: RosService>() -> (String, String) {
    (
        format!("{}/srv/{}_Request", S::PACKAGE, S::NAME),
        format!("{}/srv/{}_Response", S::PACKAGE, S::NAME),
    )
}

#[test]
fn rust_messages_match_rclpy_bytes() {
    let _group = crate::common::exclusive_group(module_path!());
    let all = values();
    let mut failures = Vec::new();
    let mut checked = Vec::new();
    macro_rules! msg_case {
        ($case:literal, $ty:ty) => {{
            checked.push($case.to_string());
            if let Err(e) = check::<$ty>($case, &msg_type::<$ty>(), &all) {
                failures.push(e);
            }
        }};
    }
    macro_rules! srv_case {
        ($case:literal, $srv:ty) => {{
            let (req, resp) = srv_types::<$srv>();
            for (suffix, ty) in [("_Request", req), ("_Response", resp)] {
                let case = format!("{}{suffix}", $case);
                checked.push(case.clone());
                let r = if suffix == "_Request" {
                    check::<<$srv as RosService>::Request>(&case, &ty, &all)
                } else {
                    check::<<$srv as RosService>::Response>(&case, &ty, &all)
                };
                if let Err(e) = r {
                    failures.push(e);
                }
            }
        }};
    }

    msg_case!("builtin_interfaces__Time", Time);
    msg_case!("std_msgs__Header", Header);
    msg_case!("std_msgs__String", StringMsg);
    msg_case!("geometry_msgs__Vector3", Vector3);
    msg_case!("geometry_msgs__Point", Point);
    msg_case!("geometry_msgs__Quaternion", Quaternion);
    msg_case!("geometry_msgs__Pose", Pose);
    msg_case!("geometry_msgs__PoseStamped", PoseStamped);
    msg_case!("geometry_msgs__PoseWithCovariance", PoseWithCovariance);
    msg_case!("geometry_msgs__Twist", Twist);
    msg_case!("geometry_msgs__TwistStamped", TwistStamped);
    msg_case!("geometry_msgs__TwistWithCovariance", TwistWithCovariance);
    msg_case!("geometry_msgs__Wrench", Wrench);
    msg_case!("sensor_msgs__JointState", JointState);
    msg_case!("nav_msgs__Odometry", Odometry);
    msg_case!("nav_msgs__Path", Path);
    msg_case!("constraint_dynamics_msgs__ConstraintForce", ConstraintForce);
    msg_case!(
        "constraint_dynamics_msgs__ConstraintForces",
        ConstraintForces
    );
    msg_case!(
        "constraint_dynamics_msgs__ConstraintForces_empty",
        ConstraintForces
    );
    msg_case!(
        "constraint_dynamics_msgs__AccelerationLimit",
        AccelerationLimit
    );
    msg_case!(
        "constraint_dynamics_msgs__AccelerationLimits",
        AccelerationLimits
    );
    srv_case!("std_srvs__Trigger", Trigger);
    srv_case!(
        "constraint_dynamics_msgs__GetConstraintForces",
        GetConstraintForces
    );
    srv_case!("constraint_dynamics_msgs__ProjectVelocity", ProjectVelocity);
    srv_case!("constraint_dynamics_msgs__Predict", Predict);
    srv_case!("constraint_dynamics_msgs__Rollouts", Rollouts);
    msg_case!("geometry_msgs__Inertia", Inertia);
    srv_case!("constraint_dynamics_msgs__SetPayload", SetPayload);
    msg_case!("geometry_msgs__WrenchStamped", WrenchStamped);
    msg_case!("visualization_msgs__Marker", Marker);
    msg_case!("visualization_msgs__MarkerArray", MarkerArray);
    msg_case!("lifecycle_msgs__State", State);
    msg_case!("lifecycle_msgs__TransitionEvent", TransitionEvent);
    srv_case!("lifecycle_msgs__ChangeState", ChangeState);
    srv_case!("lifecycle_msgs__GetState", GetState);
    srv_case!("lifecycle_msgs__GetAvailableStates", GetAvailableStates);
    srv_case!(
        "lifecycle_msgs__GetAvailableTransitions",
        GetAvailableTransitions
    );

    // Every golden case is checked by some Rust type.
    let mut unchecked: Vec<_> = all
        .keys()
        .filter(|k| !checked.contains(k))
        .cloned()
        .collect();
    unchecked.sort();
    assert!(
        unchecked.is_empty(),
        "golden cases without a Rust check: {unchecked:?}"
    );
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        checked.len(),
        failures.join("\n\n")
    );
}

/// The golden Odometry's covariances really are 36 distinct numbers, so a
/// transposed or shifted layout would be caught.
#[test]
fn golden_covariances_are_distinct() {
    let _group = crate::common::exclusive_group(module_path!());
    let all = values();
    let odom: Odometry =
        serde_json::from_value(all["nav_msgs__Odometry"]["value"].clone()).unwrap();
    for cov in [odom.pose.covariance, odom.twist.covariance] {
        let mut c = cov.to_vec();
        c.sort_by(f64::total_cmp);
        c.dedup();
        assert_eq!(c.len(), 36);
    }
}
