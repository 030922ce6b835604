//! The predictor's logic without DDS: messages in, messages out, on the ROS clock.

use super::*;
use crate::convert::time_plus;
use crate::params::CommonParams;
use constraint_dynamics::predict::PredictionRequest;

pub(super) fn node(fallback: &str) -> PredictorNode {
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../params/suite_diff_drive.yaml"
    );
    node_on(scene, fallback)
}

/// The predictor on the scene file `scene`, its command's `fallback`.
fn node_on(scene: &str, fallback: &str) -> PredictorNode {
    let fallback = serde_yaml::from_str(fallback).unwrap();
    let mut common = CommonParams::default();
    common.model.scene_file = scene.into();
    let mut params = NodeParams::<PredictorParams> {
        common,
        node: PredictorParams::default(),
    };
    params.node.command.fallback = fallback;
    params.node.command.timeout = 0.5;
    params.node.horizon = 1.0;
    let robot = Robot::load(&params.common).unwrap();
    PredictorNode::new(robot, params, NodeLog::new("test")).unwrap()
}

pub(super) fn tick(n: &mut PredictorNode, now: Time) -> PeriodicOutput {
    let mut out = None;
    n.tick(now, &mut |o| out = Some(o)).unwrap();
    *out.expect("a tick publishes")
}

fn forward(t: &Twist) -> f64 {
    t.linear.x
}

/// A command is used while it is younger than `command.timeout` on the ROS clock, whatever the
/// wall clock does; then the fallback (stop) applies.
#[test]
fn command_timeout_runs_on_the_ros_clock() {
    let mut n = node("stop");
    let t0 = Time::from_nanos(1_000_000_000_000); // a simulation's /clock, far from wall time
    let cmd = Twist {
        linear: crate::msg::geometry_msgs::Vector3 {
            x: 0.5,
            y: 0.0,
            z: 0.0,
        },
        ..Default::default()
    };
    n.handle(PredictorInput::Command(cmd), t0, &mut |_| {});
    // 0.4 s of ROS time later: the command holds; the PI-driven base speeds up towards 0.5 m/s.
    let fresh = tick(&mut n, time_plus(t0, 0.4));
    let v_fresh = forward(&fresh.odom.twist.twist);
    assert!(
        v_fresh > 0.3 && v_fresh < 0.55,
        "v at the horizon under 0.5 m/s: {v_fresh}"
    );
    // The odometry is stamped start + horizon on the ROS clock.
    assert_eq!(
        fresh.odom.header.stamp.to_nanos(),
        time_plus(t0, 1.4).to_nanos()
    );
    // 0.6 s later (> timeout): stop, the predicted base stays at rest.
    let stale = tick(&mut n, time_plus(t0, 0.6));
    let v_stale = forward(&stale.odom.twist.twist);
    assert!(
        v_stale.abs() < 1e-9,
        "v at the horizon after the timeout: {v_stale}"
    );
}

/// The forces published at the start state: the two rolling contacts, in the odom frame, with
/// Jᵀλ per coordinate; at rest on a level floor no tangential force is needed, and the planar
/// base's wheels are each pressed by half the weight M g / 2 (urdf/diff_drive.urdf: M = 9.2 kg).
#[test]
fn forces_at_rest_need_no_friction() {
    let mut n = node("stop");
    let out = tick(&mut n, Time::from_nanos(0));
    let f = &out.forces;
    assert_eq!(f.header.frame_id, "odom");
    assert_eq!(f.constraints.len(), 2);
    for c in &f.constraints {
        assert_eq!(c.kind, "rolling");
        assert!(
            c.tangential_force.abs() < 1e-9,
            "{}: {}",
            c.name,
            c.tangential_force
        );
        assert!(!c.slipping);
        assert!(
            (c.normal_force - 9.2 * 9.81 / 2.0).abs() < 1e-12,
            "{}",
            c.normal_force
        );
    }
    assert_eq!(f.generalized_force.len(), f.v_names.len());
    assert_eq!(out.path.poses.len(), 51, "1 s at 0.02 s samples, both ends");
}

/// The diff drive moving at (v, ω) from yaw θ₀, its odometry at `now`.
fn feed_state(n: &mut PredictorNode, (th0, v, w): (f64, f64, f64), pose_cov: [f64; 36], now: Time) {
    use crate::msg::geometry_msgs::Vector3;
    let (r, c) = (0.05, 0.17);
    let mut od = Odometry::default();
    od.pose.pose.orientation = crate::convert::quaternion_from_yaw(th0);
    od.pose.pose.position.x = 1.0;
    od.pose.covariance = pose_cov;
    od.twist.twist = Twist {
        linear: Vector3 {
            x: v,
            y: 0.0,
            z: 0.0,
        },
        angular: Vector3 {
            x: 0.0,
            y: 0.0,
            z: w,
        },
    };
    let js = crate::msg::sensor_msgs::JointState {
        name: vec!["left_wheel_joint".into(), "right_wheel_joint".into()],
        position: vec![0.0, 0.0],
        velocity: vec![(v - c * w) / r, (v + c * w) / r],
        ..Default::default()
    };
    let model = n.robot.model().clone();
    let st = n.robot.state_mut();
    st.apply_odometry(&model, &od).unwrap();
    st.apply_joint_state(&js).unwrap();
    st.odom_at = Some(now);
    st.joint_states_at = Some(now);
    let cmd = Twist {
        linear: Vector3 {
            x: v,
            y: 0.0,
            z: 0.0,
        },
        angular: Vector3 {
            x: 0.0,
            y: 0.0,
            z: w,
        },
    };
    n.handle(PredictorInput::Command(cmd), now, &mut |_| {});
}

/// Σ(T) = Φ Σ₀ Φᵀ for the unicycle at constant (v, ω) with uncertainty in x, y, yaw only:
/// x(T) = x₀ + (v/ω)(sin(θ₀ + ωT) − sin θ₀), y(T) = y₀ − (v/ω)(cos(θ₀ + ωT) − cos θ₀),
/// θ(T) = θ₀ + ωT, so Φ = [[1, 0, −Δy], [0, 1, Δx], [0, 0, 1]] over (x, y, yaw) in the odom
/// frame. Rows/columns (x, y, yaw) ↦ REP-103 indices (0, 1, 5).
fn unicycle_covariance(s0: [[f64; 3]; 3], (th0, v, w): (f64, f64, f64), t: f64) -> [[f64; 3]; 3] {
    let dx = v / w * ((th0 + w * t).sin() - th0.sin());
    let dy = -v / w * ((th0 + w * t).cos() - th0.cos());
    let phi = [[1.0, 0.0, -dy], [0.0, 1.0, dx], [0.0, 0.0, 1.0]];
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = (0..3)
                .flat_map(|a| (0..3).map(move |b| (a, b)))
                .map(|(a, b)| phi[i][a] * s0[a][b] * phi[j][b])
                .sum();
        }
    }
    out
}

fn rep103(s: [[f64; 3]; 3]) -> [f64; 36] {
    let idx = [0, 1, 5];
    let mut c = [0.0; 36];
    for a in 0..3 {
        for b in 0..3 {
            c[6 * idx[a] + idx[b]] = s[a][b];
        }
    }
    c
}

/// A correlated, anisotropic odom-frame start covariance at yaw 0.3 rad, through the node's
/// conversion (odom → base frame), the core's propagation and back: the predicted odometry's
/// pose covariance is the unicycle's Φ Σ₀ Φᵀ at the horizon (1 s), entry by entry. The
/// floors are set negligible (1e-9 → 1e-18 variance).
#[test]
fn predicted_pose_covariance_is_the_unicycle_closed_form() {
    let mut n = node("stop");
    n.params.node.covariance.position_floor = 1e-9;
    n.params.node.covariance.orientation_floor = 1e-9;
    let s0 = [
        [0.01, 0.002, 0.001],
        [0.002, 0.0064, -0.0005],
        [0.001, -0.0005, 0.0025],
    ];
    let motion = (0.3, 0.5, 0.4);
    let t0 = Time::from_nanos(5_000_000_000);
    feed_state(&mut n, motion, rep103(s0), t0);
    let out = tick(&mut n, t0);
    let want = unicycle_covariance(s0, motion, 1.0);
    let got = &out.odom.pose.covariance;
    let idx = [0, 1, 5];
    let mut worst: f64 = 0.0;
    for a in 0..3 {
        for b in 0..3 {
            let g = got[6 * idx[a] + idx[b]];
            worst = worst.max((g - want[a][b]).abs());
        }
    }
    println!(
        "|Σ − Φ Σ₀ Φᵀ| at 1 s: {worst:.3e} (var x {:.6e}), tick {:.1} ms",
        got[0],
        out.compute_s * 1e3
    );
    // `/diagnostics` carries the tick's work — the covariance's linearized steps: the PI wheel
    // controllers, whose torque changes at every 1 ms control tick, refuse every chunk longer
    // than one step, so about one per step over the 1 s horizon; refused tries of longer
    // chunks back off (covariance/chunks.rs): achieved 1 021, 1 951 before — and the reason
    // when a tick does not fit the period.
    let work = |n: &PredictorNode| {
        let d = n.diagnostics();
        d.iter()
            .find(|v| v.key == "last prediction work")
            .map(|v| v.value.clone())
            .expect("work in /diagnostics")
    };
    let with = work(&n);
    let count = |w: &str, what: &str| -> usize {
        let before = w.split(what).next().unwrap().trim_end();
        before.rsplit(' ').next().unwrap().parse().unwrap()
    };
    let (steps, lin) = (count(&with, " steps"), count(&with, " covariance"));
    assert!(steps == 1000 && (1000..=1030).contains(&lin), "{with}");
    n.params.node.rate = 0.01;
    assert_eq!(n.rate_shortfall(), None, "a 100 s period: {with}");
    n.params.node.rate = 1e3;
    let why = n.rate_shortfall().expect("a 1 ms period is overrun");
    assert!(
        why.starts_with("a tick takes") && why.contains("≥ the 1 ms period"),
        "{why}"
    );
    n.params.node.rate = 10.0;
    n.params.node.covariance.propagate = false;
    let plain = tick(&mut n, t0);
    assert!(
        work(&n).ends_with(" 0 covariance linearizations"),
        "{}",
        work(&n)
    );
    println!(
        "the same prediction without covariance: {:.1} ms",
        plain.compute_s * 1e3
    );
    // Achieved 6e-7: the PI wheel controllers' tracking error moves Δx, Δy by ~0.1 mm.
    assert!(
        worst < 2e-6,
        "|Σ − Φ Σ₀ Φᵀ| = {worst:e}: {got:?} vs {want:?}"
    );
    // z, roll, pitch carry the floors only.
    assert!(got[14] < 1e-12 && got[21] < 1e-12 && got[28] < 1e-12);
}

/// `state.stale_behaviour: stop`: no prediction once the inputs are older than
/// `state.timeout`, a WARN on `/diagnostics`, predictions again when they return. `warn`:
/// predictions go on, with the start covariance grown by the process noise over the age.
#[test]
fn stale_inputs_stop_or_warn_and_recover() {
    let mut n = node("stop");
    let t0 = Time::from_nanos(5_000_000_000);
    let s0 = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.0025]];
    let motion = (0.0, 0.5, 0.4);
    feed_state(&mut n, motion, rep103(s0), t0);
    let ticks = |n: &mut PredictorNode, dt: f64| {
        let mut got = None;
        n.tick(time_plus(t0, dt), &mut |o| got = Some(o)).unwrap();
        got
    };
    assert!(ticks(&mut n, 0.45).is_some(), "0.45 s < timeout 0.5 s");
    assert!(n.warnings().is_empty());
    assert!(ticks(&mut n, 0.55).is_none(), "0.55 s > timeout: stopped");
    let w = n.warnings();
    assert!(
        w.len() == 1 && w[0].contains("odom") && w[0].contains("predictions stopped"),
        "{w:?}"
    );
    // Inputs return.
    feed_state(&mut n, motion, rep103(s0), time_plus(t0, 0.9));
    let fresh = ticks(&mut n, 0.95).expect("predicting again");
    assert!(n.warnings().is_empty());

    // warn, with acceleration noise 0.5 (m/s²)/√Hz on x: predictions go on, and the pose
    // variance grows with the age.
    let mut scene = n.robot.scene().clone();
    let x = scene.model.v_names[0].clone();
    scene.file.uncertainty.acceleration_noise.insert(x, 0.5);
    let mut params = n.params.clone();
    params.common.state.stale_behaviour = crate::params::StaleBehaviour::Warn;
    let robot = Robot::from_scene(scene, &params.common).unwrap();
    let mut n = PredictorNode::new(robot, params, NodeLog::new("test")).unwrap();
    feed_state(&mut n, motion, rep103(s0), t0);
    let young = ticks(&mut n, 0.1).unwrap();
    let old = ticks(&mut n, 1.5).expect("warn: still predicting");
    assert!(
        n.warnings()[0].contains("covariance grown"),
        "{:?}",
        n.warnings()
    );
    let (vy, vo, vf) = (
        young.odom.pose.covariance[0],
        old.odom.pose.covariance[0],
        fresh.odom.pose.covariance[0],
    );
    // The start's x variance alone grows by σ² (1.5³ − 0.1³)/3 = 0.281 m² from 0.1 to 1.5 s
    // (its correlation with the velocity noise adds, the wheel controllers damp the latter).
    println!("var x at the horizon: fresh {vf:.6}, age 0.1 s {vy:.6}, age 1.5 s {vo:.6}");
    assert!(vo > vy + 0.25, "var x: age 1.5 s {vo}, 0.1 s {vy}");
    assert!(vy > vf, "with noise {vy} vs without {vf}");
}

/// A joint-noise entry for a joint the model does not have is refused when the node is built,
/// naming the parameter and the model's joints.
#[test]
fn joint_noise_for_an_unknown_joint_is_refused() {
    let n = node("stop");
    let mut params = n.params.clone();
    params
        .common
        .state
        .joint_noise
        .joints
        .insert("arm_elbow".into(), vec![0.001, 0.01]);
    let robot = n.robot.clone();
    let e = PredictorNode::new(robot, params, NodeLog::new("test"))
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("state.joint_noise.joints.arm_elbow") && e.contains("left_wheel_joint"),
        "{e}"
    );
}

/// Every prediction judges its contacts: at rest nothing breaks and the planar base's lift-off is
/// listed unchecked; commanded 0.5 m/s from rest, the PI wheel controllers saturate at the URDF
/// effort (5 N·m, tests/it/propagation_actuator_forces.rs) and `/diagnostics` WARNs of a slip at the
/// first sample. urdf/diff_drive.urdf: M = 8 + 2 × 0.5 + 0.2 kg, r = 0.05 m, I_w = 0.000625 kg·m²;
/// a = 2 τ / (r (M + 2 I_w / r²)), each wheel pushed with M a / 2 against
/// μ N = 0.8 × M g / 2 (`slip.planar_normal_force` 0: half the weight).
#[test]
fn a_predicted_slip_is_a_diagnostics_warning() {
    let mut n = node("stop");
    let t0 = Time::from_nanos(0);
    tick(&mut n, t0);
    assert!(n.warnings().is_empty(), "{:?}", n.warnings());
    let value = |n: &PredictorNode, key: &str| {
        let d = n.diagnostics();
        d.iter().find(|v| v.key == key).expect(key).value.clone()
    };
    assert_eq!(
        value(&n, "predicted contact break"),
        "none within the horizon"
    );
    assert_eq!(
        value(&n, "unchecked contact limits"),
        "lift_off: left_wheel_contact, lift_off: right_wheel_contact"
    );
    let cmd = Twist {
        linear: crate::msg::geometry_msgs::Vector3 {
            x: 0.5,
            y: 0.0,
            z: 0.0,
        },
        ..Default::default()
    };
    n.handle(PredictorInput::Command(cmd), t0, &mut |_| {});
    let out = tick(&mut n, t0);
    let (m, r, i_w, g, mu) = (9.2, 0.05, 0.000625, 9.81, 0.8);
    let a = 2.0 * 5.0 / (r * (m + 2.0 * i_w / (r * r)));
    let used = (m * a / 2.0) / (mu * m * g / 2.0);
    // `~/constraint_forces` at the start state: each wheel needs M a / 2 > μ M g / 2.
    for c in &out.forces.constraints {
        let rel = (c.tangential_force - m * a / 2.0).abs() / (m * a / 2.0);
        assert!(
            c.slipping && rel < 1e-9,
            "{}: {}",
            c.name,
            c.tangential_force
        );
        assert!(
            (c.normal_force - m * g / 2.0).abs() < 1e-12,
            "{}",
            c.normal_force
        );
    }
    assert_eq!(
        value(&n, "slipping contacts"),
        "left_wheel_contact, right_wheel_contact"
    );
    let want = format!("slip at t=0.00 s on left_wheel_contact (friction used {used:.2} × μ)");
    assert_eq!(n.warnings(), std::slice::from_ref(&want));
    assert_eq!(value(&n, "predicted contact break"), want);
}

/// A drive that follows its commands through a lag (`actuators.diff_drive.command_lag`): the
/// node runs every command it receives through the lag on the ROS clock, and predicts from the
/// lagged command where the commands left it — 0.1 s after a step from rest to 0.5 m/s under
/// τ = 0.2 s, 0.5 (1 − e^(−0.5)) m/s — as the core predicts from that lagged command.
#[test]
fn a_lagging_drive_is_predicted_from_where_the_commands_left_the_lag() {
    let dir = std::env::temp_dir().join(format!("cd_predictor_lag_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let params_dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../params");
    let suite = std::fs::read_to_string(format!("{params_dir}/suite_diff_drive.yaml")).unwrap();
    let ki = "    ki: 20.0                     # [N·m/rad]\n";
    assert!(suite.contains(ki), "the suite scene's diff drive moved");
    let lagged = (suite.replace(ki, &format!("{ki}    command_lag: 0.2\n")))
        .replace("urdf: ../urdf/", &format!("urdf: {params_dir}/../urdf/"));
    let scene_file = dir.join("lagged.yaml");
    std::fs::write(&scene_file, lagged).unwrap();
    let mut n = node_on(&scene_file.display().to_string(), "stop");
    let t0 = Time::from_nanos(1_000_000_000_000);
    let twist = |x: f64| Twist {
        linear: crate::msg::geometry_msgs::Vector3 { x, y: 0.0, z: 0.0 },
        ..Default::default()
    };
    n.handle(PredictorInput::Command(twist(0.0)), t0, &mut |_| {});
    let step = time_plus(t0, 1.0);
    n.handle(PredictorInput::Command(twist(0.5)), step, &mut |_| {});
    let out = tick(&mut n, time_plus(step, 0.1));

    let scene = Scene::load(&scene_file).unwrap();
    let mut core = Predictor::from_scene(&scene).unwrap();
    let commands = [(
        0.0,
        constraint_dynamics::actuators::Command {
            base_twist: Some([0.5, 0.0]),
            ..Default::default()
        },
    )];
    let mut x_at = |lagged: Option<[f64; 2]>| {
        let request = PredictionRequest {
            commands: &commands,
            lagged_command: lagged,
            ..PredictionRequest::new(&scene.q0, &scene.v0).horizon(1.0)
        };
        core.predict(&request).unwrap().samples.last().unwrap().q[0]
    };
    let lagged = 0.5 * (1.0 - (-0.5f64).exp());
    let (expected, unlagged) = (x_at(Some([lagged, 0.0])), x_at(None));
    let x = out.odom.pose.pose.position.x;
    // The same prediction: achieved 0.
    assert!((x - expected).abs() < 1e-12, "{x} m against {expected}");
    assert!(
        (x - unlagged).abs() > 0.01,
        "{x} m, without the lag's start {unlagged}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
