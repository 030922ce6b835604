//! The rosbag2 reader (`bag/`) on the recorded test logs (tests/data/logs/, written by
//! mcap-ros2-support from MuJoCo, tools/logs/make_logs.py) and on bags written here by the mcap
//! crate's writer: message counts and values as recorded, both bag forms, and every bad input
//! (truncated and byte-flipped files, missing topics, wrong types, time going back, gaps,
//! unstamped commands on another clock) a clear error naming the file or topic and time —
//! never a panic. Opens no DDS participant.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use byteorder::LittleEndian;
use constraint_dynamics::Scene;
use constraint_dynamics::replay::{EvaluationSettings, evaluate};
use constraint_dynamics_nodes::bag::{BagTopics, read_recording};
use constraint_dynamics_nodes::msg::builtin_interfaces::Time;
use constraint_dynamics_nodes::msg::geometry_msgs::Twist;
use constraint_dynamics_nodes::msg::nav_msgs::Odometry;
use constraint_dynamics_nodes::msg::sensor_msgs::JointState;
use constraint_dynamics_nodes::msg::std_msgs::Header;
use serde::Serialize;

fn logs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/logs")
}

fn scene() -> Scene {
    Scene::load(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../params/suite_mobile_manipulator.yaml"),
    )
    .unwrap()
}

/// The generator's drives: 20 s; /odom and the truth at 50 Hz from 0 s (1001), /joint_states at
/// 50 Hz from 5 ms (1000), /cmd_vel at 20 Hz (400).
#[test]
fn recorded_logs_read_in_both_bag_forms() {
    let _group = crate::common::exclusive_group(module_path!());
    let truth = BagTopics {
        reference: Some("/ground_truth/odom".into()),
        ..BagTopics::default()
    };
    for bag in ["validation_smooth.mcap", "validation_steps"] {
        let rec = read_recording(&logs().join(bag), &truth).unwrap();
        assert_eq!(rec.odometry.samples.len(), 1001, "{bag}");
        assert_eq!(rec.reference.samples.len(), 1001, "{bag}");
        assert_eq!(rec.joint_states.samples.len(), 1000, "{bag}");
        assert_eq!(rec.commands.samples.len(), 400, "{bag}");
        let (t0, t1) = rec.odometry.span().unwrap();
        assert_eq!(t1 - t0, 20_000_000_000, "{bag}");
        // make_logs.py: T0 = 1.7e9 s, joint states 5 ms after the odometry, the truth exact.
        assert_eq!(t0, 1_700_000_000_000_000_000);
        assert_eq!(rec.joint_states.samples[0].0 - t0, 5_000_000);
        let (_, o) = &rec.odometry.samples[1];
        assert_eq!(o.pose_covariance[0], 0.002 * 0.002);
        assert_eq!(o.pose_covariance[35], 0.002 * 0.002);
        assert_eq!(o.twist_covariance[35], 0.01 * 0.01);
        assert!(
            rec.reference
                .samples
                .iter()
                .all(|(_, r)| r.pose_covariance == [0.0; 36])
        );
        let js = &rec.joint_states.samples[0].1;
        assert_eq!(js.name[..2], ["left_wheel_joint", "right_wheel_joint"]);
        assert_eq!(
            (js.position.len(), js.velocity.len(), js.effort.len()),
            (6, 6, 6)
        );
        // The odometry is the truth plus noise of σ 2 mm: its rms difference says so.
        let n = rec.odometry.samples.len() as f64;
        let rms = (rec.odometry.samples.iter().zip(&rec.reference.samples))
            .map(|((_, o), (_, r))| (o.pose.position[0] - r.pose.position[0]).powi(2))
            .sum::<f64>()
            / n;
        assert!(
            (0.0017..0.0023).contains(&rms.sqrt()),
            "{bag}: rms {}",
            rms.sqrt()
        );
    }
}

fn err(path: &Path, topics: &BagTopics) -> String {
    read_recording(path, topics).unwrap_err().to_string()
}

#[test]
fn missing_topics_wrong_types_and_bad_paths_are_named() {
    let _group = crate::common::exclusive_group(module_path!());
    let bag = logs().join("calibration.mcap");
    let e = err(
        &bag,
        &BagTopics {
            odom: "/wheel/odom".into(),
            ..BagTopics::default()
        },
    );
    assert!(
        e.contains("no odometry topic '/wheel/odom'")
            && e.contains("/odom [nav_msgs/msg/Odometry]"),
        "{e}"
    );
    let e = err(
        &bag,
        &BagTopics {
            odom: "/cmd_vel".into(),
            ..BagTopics::default()
        },
    );
    assert!(
        e.contains(
            "topic '/cmd_vel' is geometry_msgs/msg/Twist (cdr); expected nav_msgs/msg/Odometry"
        ),
        "{e}"
    );
    let e = err(&logs().join("nothing_here.mcap"), &BagTopics::default());
    assert!(
        e.contains("nothing_here.mcap") && e.contains("No such file"),
        "{e}"
    );
    let dir = std::env::temp_dir().join(format!("cd_bag_nometa_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let e = err(&dir, &BagTopics::default());
    assert!(e.contains("metadata.yaml"), "{e}");
    std::fs::write(dir.join("metadata.yaml"), "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: sqlite3\n  relative_file_paths: [a.db3]\n").unwrap();
    let e = err(&dir, &BagTopics::default());
    assert!(
        e.contains("storage 'sqlite3': only mcap bags are read"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Every 1009th prefix of a recorded file, and 300 copies with 1–4 bytes flipped at seeded
/// places: each is read to a recording or refused with an error naming the file, and a
/// recording is evaluated or refused — no panic, no hang.
#[test]
fn truncated_and_byte_flipped_files_are_refused_clearly() {
    let _group = crate::common::exclusive_group(module_path!());
    let bytes = std::fs::read(logs().join("validation_smooth.mcap")).unwrap();
    let dir = std::env::temp_dir().join(format!("cd_bag_fuzz_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("fuzzed.mcap");
    let scene = scene();
    let quick = EvaluationSettings {
        horizons_s: vec![0.25],
        every_s: 5.0,
        ..EvaluationSettings::default()
    };
    let mut truncated_refused = 0;
    for cut in (0..bytes.len()).step_by(1009) {
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let e = err(&path, &BagTopics::default());
        assert!(e.contains("fuzzed.mcap"), "cut at {cut}: {e}");
        truncated_refused += 1;
    }
    assert!(truncated_refused > 300);
    let mut seed: u64 = 0x5eed;
    let mut next = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 33) as usize
    };
    let (mut read, mut refused) = (0, 0);
    for _ in 0..300 {
        let mut b = bytes.clone();
        for _ in 0..1 + next() % 4 {
            let i = next() % b.len();
            b[i] ^= 1 << (next() % 8);
        }
        std::fs::write(&path, &b).unwrap();
        match read_recording(&path, &BagTopics::default()) {
            Ok(rec) => {
                read += 1;
                if let Err(e) = evaluate(&scene, &rec, &quick) {
                    assert!(!e.to_string().is_empty());
                }
            }
            Err(e) => {
                refused += 1;
                assert!(e.to_string().contains("fuzzed.mcap"), "{e}");
            }
        }
    }
    // Flips inside the compressed chunks break their CRC; a few land in the summary or padding
    // and leave the messages intact.
    assert!(refused > 200, "{refused} refused, {read} read");
    std::fs::remove_dir_all(&dir).ok();
}

/// A bag written here: /odom, /joint_states and /cmd_vel (Twist) at the given stamps [ns] and
/// log-time offset [ns], the odometry with `covariance` on x, y, yaw.
struct Written {
    odom: Vec<i64>,
    joints: Vec<i64>,
    commands: Vec<i64>,
    log_offset: i64,
    covariance: f64,
}

fn cdr<T: Serialize>(msg: &T) -> Vec<u8> {
    let mut out = vec![0, 1, 0, 0];
    out.extend(cdr_encoding::to_vec::<T, LittleEndian>(msg).unwrap());
    out
}

fn write_bag(path: &Path, w: &Written) {
    let mut buf = Cursor::new(Vec::new());
    let mut writer = mcap::Writer::new(&mut buf).unwrap();
    let none = BTreeMap::new();
    let mut channel = |name: &str, topic: &str| {
        let s = writer.add_schema(name, "ros2msg", b"").unwrap();
        writer.add_channel(s, topic, "cdr", &none).unwrap()
    };
    let (c_odom, c_js, c_cmd) = (
        channel("nav_msgs/msg/Odometry", "/odom"),
        channel("sensor_msgs/msg/JointState", "/joint_states"),
        channel("geometry_msgs/msg/Twist", "/cmd_vel"),
    );
    // (file position [ns of the nominal timeline], stamp, channel, data): the file keeps the
    // nominal order whatever the stamps say, as a recorder writes in arrival order.
    let mut messages: Vec<(i64, i64, u16, Vec<u8>)> = Vec::new();
    for (k, &t) in w.odom.iter().enumerate() {
        let mut od = Odometry {
            header: Header {
                stamp: Time::from_nanos(t),
                frame_id: "odom".into(),
            },
            ..Default::default()
        };
        for i in [0, 7, 35] {
            od.pose.covariance[i] = w.covariance;
        }
        messages.push((k as i64 * 20_000_000, t, c_odom, cdr(&od)));
    }
    for (k, &t) in w.joints.iter().enumerate() {
        let js = JointState {
            header: Header {
                stamp: Time::from_nanos(t),
                frame_id: String::new(),
            },
            name: vec!["left_wheel_joint".into(), "right_wheel_joint".into()],
            position: vec![0.0, 0.0],
            velocity: vec![0.0, 0.0],
            effort: vec![],
        };
        messages.push((k as i64 * 20_000_000 + 5_000_000, t, c_js, cdr(&js)));
    }
    for (k, &t) in w.commands.iter().enumerate() {
        messages.push((k as i64 * 50_000_000, t, c_cmd, cdr(&Twist::default())));
    }
    messages.sort_by_key(|m| m.0);
    let mut writer = writer;
    for (k, (_, t, ch, data)) in messages.iter().enumerate() {
        let log = (t + w.log_offset).max(0) as u64;
        let header = mcap::records::MessageHeader {
            channel_id: *ch,
            sequence: k as u32,
            log_time: log,
            publish_time: log,
        };
        writer.write_to_known_channel(&header, data).unwrap();
    }
    writer.finish().unwrap();
    drop(writer);
    std::fs::write(path, buf.into_inner()).unwrap();
}

/// Stamps every `period` ms over `n` samples, from `start` ms.
fn stamps(start: i64, period: i64, n: i64) -> Vec<i64> {
    (0..n)
        .map(|k| 1_000_000_000_000 + (start + k * period) * 1_000_000)
        .collect()
}

#[test]
fn time_jumps_gaps_clocks_and_missing_covariance() {
    let _group = crate::common::exclusive_group(module_path!());
    let dir = std::env::temp_dir().join(format!("cd_bag_written_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("written.mcap");
    let scene = scene();
    let quick = EvaluationSettings {
        horizons_s: vec![0.25],
        ..EvaluationSettings::default()
    };
    let base = || Written {
        odom: stamps(0, 20, 150),
        joints: stamps(5, 20, 150),
        commands: stamps(0, 50, 60),
        log_offset: 0,
        covariance: 4e-6,
    };
    // As written: read and evaluated. A robot at rest stays there, but for the arm: held where
    // it is, it sags under gravity until its PD pushes back, and the base recoils by micrometres.
    write_bag(&path, &base());
    let rec = read_recording(&path, &BagTopics::default()).unwrap();
    let ev = evaluate(&scene, &rec, &quick).unwrap();
    assert_eq!(ev.starts, 6);
    let h = &ev.horizons[0];
    assert!(
        h.position_error_m.max < 2e-5 && h.yaw_error_rad.max < 1e-12,
        "{h:?}"
    );
    // No covariance at all: still evaluated, on the floors.
    write_bag(
        &path,
        &Written {
            covariance: 0.0,
            ..base()
        },
    );
    let rec = read_recording(&path, &BagTopics::default()).unwrap();
    assert_eq!(evaluate(&scene, &rec, &quick).unwrap().starts, 6);
    // /odom going back 60 ms at 1.000 s.
    let mut odom = stamps(0, 20, 150);
    odom[50] -= 60_000_000 + 20_000_000;
    write_bag(&path, &Written { odom, ..base() });
    let rec = read_recording(&path, &BagTopics::default()).unwrap();
    let e = evaluate(&scene, &rec, &quick).unwrap_err().to_string();
    assert_eq!(
        e,
        "/odom: time goes back by 0.060 s at 0.920 s (stamp 1000.920000000)"
    );
    // /joint_states silent for 0.8 s after 1.005 s.
    let joints: Vec<i64> = (stamps(5, 20, 150).into_iter())
        .filter(|t| !(1_001_010_000_000..1_001_800_000_000).contains(t))
        .collect();
    write_bag(&path, &Written { joints, ..base() });
    let rec = read_recording(&path, &BagTopics::default()).unwrap();
    let e = evaluate(&scene, &rec, &quick).unwrap_err().to_string();
    assert!(
        e.starts_with("/joint_states: no message for 0.800 s after 1.005 s (stamp 1001.005000000)"),
        "{e}"
    );
    // Unstamped commands timed by a log clock 3 s off the stamps.
    write_bag(
        &path,
        &Written {
            log_offset: 3_000_000_000,
            ..base()
        },
    );
    let e = err(&path, &BagTopics::default());
    assert!(
        e.contains("'/cmd_vel' is geometry_msgs/msg/Twist (no stamp)") && e.contains("-3.000 s"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
