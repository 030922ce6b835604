//! The predictor scoring its own predictions on recorded drives of a robot that is not its
//! model, replayed through a real ROS 2 peer (rclpy with rmw_fastrtps_cpp,
//! `nodes/tests/peers/replay_peer.py`): the peer reads a log of tests/data/logs/ (MuJoCo's
//! mobile manipulator with a heavier chassis and worn, scrubbing tyres; odometry noise σ 2 mm,
//! 2 mrad) with the `mcap` reader, decodes it with rclpy and publishes /odom, /joint_states
//! and /cmd_vel at their recorded times with /clock, at twice the recorded rate, into the suite
//! of params/default.yaml under use_sim_time, every `monitor.*` at its default.
//! - validation_smooth.mcap (20 s, a Nav2-like drive): no WARN from the monitor, every status
//!   OK, and each horizon's medians (position, yaw, NEES) the same as those of an independent
//!   computation within a factor 2 (NEES 3): the offline replay (`constraint_dynamics evaluate`'s
//!   library function) of the same log, its predictions whose command held over the horizon,
//!   the last of them due by the log's end, as many as the node's window holds (≤
//!   `monitor.window`: the node ticks on /clock as fast as it keeps up), the NEES recomputed
//!   here with the monitor's documented motion allowance;
//! - payload_3kg.mcap (10 s, the robot carrying 3 kg at tool0 the suite is not told of, its arm
//!   holding the tool above the wheel axle): one WARN naming the shoulder pitch's effort and a
//!   payload, the shoulder's median effort error the closed form −M·g·d at the logged arm pose
//!   (the peer's) within 0.75 N·m at 0.25 and 0.5 s, and at 1 s between 0.75 N·m below it and
//!   1.5 N·m above (the heavier robot's lagging accelerations swing arm and payload). The
//!   23 % heavier robot may also drive off its model's odometry: a WARN then calls both (or
//!   the efforts first, then both, when the efforts' window fills first);
//! - slippery_floor.mcap (10 s, the same kind of drive on a floor the tyres grip with μ 0.1,
//!   the scene's rolling contacts gripping whatever it takes): the wheels spin in the ramps and
//!   the base lags and slides, while the command ramps: the predictions then are not scored,
//!   but the measured states lie off the rolling constraints (the wheels' speeds against the
//!   odometry's twist). A WARN naming a slippery floor (the slip statistic, or the odometry off
//!   the predictions), and none naming the efforts alone;
//! - command_lag.mcap (20 s of raw command steps to a drive whose wheel-speed targets follow
//!   the commands through a first-order lag of 0.15 s the scene does not declare): a WARN
//!   naming a late drive, its lag beyond the model's own response (the monitor's fit, at 1 s)
//!   above the threshold and at most the simulator's 0.15 s.
//!
//! Needs root and the peer venv (`CD_ROS2_VENV`): `#[ignore]`d in a plain `cargo test`, run by
//! `tools/test.sh`; a missing prerequisite fails the test.

use crate::common;

use std::path::Path;
use std::time::Duration;

use common::*;
use constraint_dynamics::Scene;
use constraint_dynamics::replay::{EvaluationSettings, Nanos, PredictionRecord, evaluate};
use constraint_dynamics_nodes::bag::{BagTopics, read_recording};
use serde_json::Value;

const TEST: &str =
    "rclpy_replayed_logs_are_scored_and_a_payload_a_slippery_floor_and_a_late_drive_named";
const HORIZONS: [f64; 3] = [0.25, 0.5, 1.0];
/// The monitor's defaults (docs/nodes.md, `monitor.*`) that define what it scores.
const WINDOW: usize = 50;
const MIN_SAMPLES: usize = 20;
const COMMAND_TOLERANCE: [f64; 2] = [0.005, 0.01];
const MOTION_ERROR: [f64; 2] = [0.02, 0.05];
/// Log seconds per wall second of the replay: the suite, on the log's time, predicts at 10 Hz
/// of it (20 a wall second, about a tenth of a core with the covariance).
const RATE: f64 = 2.0;
const WARN: &str = "predictions off what arrives";

fn replay(what: &str, log: &str, extra: &[String]) -> (Value, SuiteProcess) {
    let python = peer_python(TEST);
    let suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--node",
            "predictor",
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            "use_sim_time:=true",
        ],
        TEST,
    );
    let bag = repo_root().join("tests/data/logs").join(log);
    let mut args = vec![
        "--bag".to_string(),
        bag.display().to_string(),
        "--rate".to_string(),
        RATE.to_string(),
    ];
    args.extend_from_slice(extra);
    let report = peer_report(&python, "replay_peer.py", &args, Duration::from_secs(45));
    if let Some(figures) = report["figures"].as_object() {
        for (k, v) in figures {
            println!("{TEST}: {what}: achieved {k}: {v}");
        }
    }
    assert_eq!(
        report["ok"],
        true,
        "replay_peer.py: {:#}\n{}",
        report["errors"],
        suite.log()
    );
    (report, suite)
}

/// The last report's status of each horizon, by horizon.
fn last_statuses(report: &Value) -> Vec<Value> {
    HORIZONS
        .iter()
        .map(|h| report["figures"]["last"][format!("prediction at {h} s")].clone())
        .collect()
}

fn number(status: &Value, key: &str) -> f64 {
    let v = status["values"][key].as_str().unwrap_or("nan");
    v.parse().unwrap_or(f64::NAN)
}

/// One test, the drives one after the other: their peers publish on the same topics.
#[test]
#[ignore = "needs root and the peer venv: run by tools/test.sh"]
fn rclpy_replayed_logs_are_scored_and_a_payload_a_slippery_floor_and_a_late_drive_named() {
    let _group = crate::common::exclusive_group(module_path!());
    if !in_namespace_or_reexec(TEST) {
        return; // the run inside the namespace passed
    }
    normal_drive();
    unannounced_payload();
    slippery_floor();
    late_drive();
}

fn normal_drive() {
    let (report, mut suite) = replay("normal drive", "validation_smooth.mcap", &[]);
    let statuses = last_statuses(&report);
    let samples: Vec<usize> = (statuses.iter())
        .map(|s| number(s, "odometry samples") as usize)
        .collect();
    let bag = repo_root().join("tests/data/logs/validation_smooth.mcap");
    let expected = offline_figures(&bag, &samples);
    let each = statuses
        .iter()
        .zip(&samples)
        .zip(HORIZONS.iter().zip(expected));
    for ((s, n), (h, e)) in each {
        println!(
            "{TEST}: {h} s: offline (position, yaw, NEES) medians of {n}: {e:?}; the node's \
             drive lag {} ± {} s",
            number(s, "drive lag beyond the model [s]"),
            number(s, "drive lag standard error [s]")
        );
        assert_eq!(s["level"], 0, "{h} s: {s:#}");
        assert!((MIN_SAMPLES..=WINDOW).contains(n), "{h} s: {s:#}");
        let node = [
            number(s, "position error median [m]"),
            number(s, "yaw error median [rad]"),
            number(s, "NEES median (chi2 3: 2.37)"),
        ];
        // Not the same predictions: the node's start at its ticks, the offline ones every
        // 0.1 s; the first odometry after the due time carried back against the last before;
        // the held command against the recorded ones. A 50-sample median spreads by ~20 %,
        // a NEES median by ~30 %.
        for (i, (n, o, factor)) in [
            (node[0], e[0], 2.0),
            (node[1], e[1], 2.0),
            (node[2], e[2], 3.0),
        ]
        .into_iter()
        .enumerate()
        {
            assert!(
                n / o < factor && o / n < factor,
                "{h} s, figure {i}: node {n} against offline {o}: {s:#}"
            );
        }
        // The heavier chassis changes the wheels' torques only while accelerating.
        let effort = number(s, "worst effort error median [N m or N]");
        assert!(effort.abs() < 1.0, "{h} s: {s:#}");
        assert!(number(s, "command changed (not scored)") > 0.0, "{s:#}");
    }
    assert_eq!(report["figures"]["highest level"], 0, "{report:#}");
    let log = suite.log();
    assert!(
        !log.contains(WARN),
        "a monitor WARN on a normal drive:\n{log}"
    );
    assert!(suite.stop(), "the suite did not stop cleanly:\n{log}");
}

fn unannounced_payload() {
    let urdf = repo_root().join("urdf/mobile_manipulator.urdf");
    let extra = ["--payload-kg", "3", "--urdf"]
        .map(str::to_string)
        .into_iter()
        .chain([urdf.display().to_string()])
        .collect::<Vec<_>>();
    let (report, mut suite) = replay("unannounced payload", "payload_3kg.mcap", &extra);
    let hold = report["figures"]["payload hold torque at the logged arm pose [N m]"]
        .as_f64()
        .expect("the peer's closed form");
    for (h, s) in HORIZONS.iter().zip(last_statuses(&report)) {
        assert_eq!(s["level"], 1, "{h} s: {s:#}");
        assert_eq!(
            s["values"]["worst effort joint"], "arm_shoulder_pitch",
            "{s:#}"
        );
        let e = number(&s, "worst effort error median [N m or N]");
        // The closed form is static. Over a longer horizon the 23 % heavier robot's speed
        // lags the model's more, and the lag's acceleration swings the arm and its payload
        // about the shoulder (first moment about 2 kg·m; the log's drive accelerates by up to
        // 1 m/s², so up to 2 N·m while accelerating). The 1 s window is also the shortest (its
        // predictions' commands change most often) and keeps the most such samples.
        // Measured off the closed form: 0.02–0.05, 0.36–0.42 and 0.45–0.90 N·m at 0.25,
        // 0.5 and 1 s, on an idle machine and on CI's.
        let (below, above) = if *h < 1.0 { (0.75, 0.75) } else { (0.75, 1.5) };
        assert!(
            e > hold - below && e < hold + above,
            "{h} s: {e} against {hold}: {s:#}"
        );
    }
    let log = suite.log();
    // One WARN per cause's onset, the efforts' and the odometry's: together (both in one
    // window) or one after the other as their windows fill; never cleared meanwhile.
    let warns: Vec<&str> = log.lines().filter(|l| l.contains(WARN)).collect();
    assert!((1..=2).contains(&warns.len()), "one WARN per onset:\n{log}");
    for w in &warns {
        let named = w.contains("arm_shoulder_pitch's effort") && w.contains("payload");
        assert!(named, "{w}");
    }
    assert!(
        !log.contains("predictions match what arrives again"),
        "{log}"
    );
    assert!(suite.stop(), "the suite did not stop cleanly:\n{log}");
}

fn slippery_floor() {
    let (report, mut suite) = replay("slippery floor", "slippery_floor.mcap", &[]);
    assert_eq!(report["figures"]["highest level"], 1, "{report:#}");
    let log = suite.log();
    let warns: Vec<&str> = log.lines().filter(|l| l.contains(WARN)).collect();
    assert!(
        !warns.is_empty(),
        "no monitor WARN on a slippery floor:\n{log}"
    );
    for w in &warns {
        println!("{TEST}: slippery floor: achieved WARN: {w}");
        let poses = w.contains("slippery floor") || w.contains("the odometry (NEES");
        assert!(poses, "a WARN that does not call the odometry: {w}");
    }
    assert!(
        warns.iter().any(|w| w.contains("slippery floor")),
        "no WARN names a slippery floor:\n{log}"
    );
    assert!(suite.stop(), "the suite did not stop cleanly:\n{log}");
}

fn late_drive() {
    let (report, mut suite) = replay("late drive", "command_lag.mcap", &[]);
    let log = suite.log();
    let warns: Vec<&str> = log.lines().filter(|l| l.contains(WARN)).collect();
    for w in &warns {
        println!("{TEST}: late drive: achieved WARN: {w}");
    }
    assert!(
        warns.iter().any(|w| w.contains("a late drive")),
        "no WARN names a late drive:\n{log}"
    );
    let s = &last_statuses(&report)[2];
    let lag = number(s, "drive lag beyond the model [s]");
    // The model's own wheel-speed loops respond in a few tens of ms, which the fit does not
    // count: it lies below the simulator's 0.15 s (offline, every 0.1 s: 0.13 s).
    assert!(lag > 0.08 && lag <= 0.15, "{lag}: {s:#}");
    assert!(suite.stop(), "the suite did not stop cleanly:\n{log}");
}

/// Per horizon, the medians of position error [m], |yaw error| [rad] and NEES over the last
/// `samples` offline predictions due by the log's end whose command held over the horizon.
fn offline_figures(bag: &Path, samples: &[usize]) -> Vec<[f64; 3]> {
    let scene = Scene::load(repo_root().join("params/suite_mobile_manipulator.yaml")).unwrap();
    let topics = BagTopics {
        odom: "/odom".into(),
        joint_states: "/joint_states".into(),
        cmd_vel: "/cmd_vel".into(),
        reference: None,
    };
    let rec = read_recording(bag, &topics).unwrap();
    let settings = EvaluationSettings {
        horizons_s: HORIZONS.to_vec(),
        every_s: 0.1,
        ..EvaluationSettings::default()
    };
    let ev = evaluate(&scene, &rec, &settings).unwrap();
    let origin = rec.origin();
    let end = rec.odometry.samples.last().unwrap().0;
    let ns = |s: f64| origin + (s * 1e9).round() as Nanos;
    // The command in force at t0 held if none in (t0, t0 + h] is off it by the tolerance.
    let held = |r: &PredictionRecord| {
        let (t0, t1) = (ns(r.t0_s), ns(r.t0_s + r.horizon_s));
        let Some((_, c0)) = rec.commands.at_or_before(t0) else {
            return false;
        };
        (rec.commands.between(t0, t1).iter())
            .all(|(_, c)| (0..2).all(|i| (c[i] - c0[i]).abs() <= COMMAND_TOLERANCE[i]))
    };
    HORIZONS
        .iter()
        .zip(samples)
        .map(|(&h, &n)| {
            let scored: Vec<&PredictionRecord> = (ev.records.iter())
                .filter(|r| r.horizon_s == h && ns(r.t0_s + h) <= end && held(r))
                .collect();
            let window = &scored[scored.len().saturating_sub(n)..];
            let nees = window.iter().map(|r| {
                let start = &rec.odometry.at_or_before(ns(r.t0_s)).unwrap().1.pose;
                nees_with_motion_error(r, start.position, yaw_of(start.orientation_xyzw))
            });
            [
                median(window.iter().map(|r| r.position_error_m)),
                median(window.iter().map(|r| r.yaw_error_rad.abs())),
                median(nees),
            ]
        })
        .collect()
}

fn yaw_of([x, y, z, w]: [f64; 4]) -> f64 {
    (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
}

fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    a - t * ((a + std::f64::consts::PI) / t).floor()
}

/// eᵀ S⁻¹ e, S = predicted + reference covariance + the motion allowance (σ = MOTION_ERROR × the
/// distance and the turn from the start), by Cramer's rule.
fn nees_with_motion_error(r: &PredictionRecord, start: [f64; 3], start_yaw: f64) -> f64 {
    let p = r.predicted;
    let travelled = (p[0] - start[0]).hypot(p[1] - start[1]);
    let turned = wrap(p[2] - start_yaw).abs();
    let extra = [
        MOTION_ERROR[0] * travelled,
        MOTION_ERROR[0] * travelled,
        MOTION_ERROR[1] * turned,
    ];
    let mut s = r.predicted_covariance;
    for (i, row) in s.iter_mut().enumerate() {
        for (x, y) in row.iter_mut().zip(&r.reference_covariance[i]) {
            *x += y;
        }
        row[i] += extra[i] * extra[i];
    }
    let e = [
        r.reference[0] - p[0],
        r.reference[1] - p[1],
        wrap(r.reference[2] - p[2]),
    ];
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&s);
    (0..3)
        .map(|k| {
            let mut m = s;
            (0..3).for_each(|i| m[i][k] = e[i]);
            e[k] * det(&m) / d
        })
        .sum()
}

fn median(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.collect();
    assert!(!v.is_empty(), "no offline prediction to take a median of");
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n % 2 {
        1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}
