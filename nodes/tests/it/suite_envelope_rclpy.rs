//! The acceleration envelope over ROS 2, with a real peer: rclpy
//! (`nodes/tests/peers/envelope_peer.py`, rmw_fastrtps_cpp) publishes the floating mobile
//! manipulator's state (moving forward at 0.2 m/s, the arm's shoulder pitch changing by phase),
//! reads `/cd_predictor/acceleration_limits` and `/diagnostics`, and runs a node
//! `velocity_smoother` whose `max_accel` / `max_decel` are declared and validated as Nav2's
//! velocity smoother does. Checked:
//! - the limits arrive at the predictor's rate (10 Hz, from the stamps and from the receipts);
//! - every message of each phase's window equals the core's envelope at the state the peer
//!   published (the library's `acceleration_envelope`, as the CLI's `envelope` computes it,
//!   with the scene's force elements), with the same binding and unchecked limits, and its
//!   braking limit equals the closed form of the caster lifting off ([`braking_closed_form`]);
//! - the bridge sets the smoother to the envelope by the documented rules (forward motion:
//!   max_accel = [a_fwd, y, min yaw], max_decel = [−d_fwd, y, −min yaw], capped by the smoother's
//!   own values, floored at `envelope.linear_floor`), tightens at once when the arm leans
//!   forward (the braking limit falls), sends nothing within the dead band, sends the floor when
//!   the braking limit is negative, and loosens no sooner than `envelope.min_interval` after the
//!   last send; `/diagnostics` shows the limits and a WARN while one is ≤ 0.
//!
//! Needs root and the peer venv: `#[ignore]`d in a plain `cargo test`, run by `tools/test.sh`
//! (Kilted and Jazzy); a missing prerequisite fails the test.

use crate::common;

use std::time::Duration;

use common::*;
use constraint_dynamics::Scene;
use constraint_dynamics::applied::applied_generalized_force;
use constraint_dynamics::envelope::{
    EnvelopeData, EnvelopeModel, EnvelopeReport, LimitReport, acceleration_envelope,
};
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::system::System;
use serde_json::Value;

const TEST: &str = "rclpy_reads_acceleration_limits_and_its_smoother_follows_them";
const SCENE: &str = "params/suite_mobile_manipulator_floating.yaml";
const RATE: f64 = 10.0; // [Hz]
const MIN_INTERVAL: f64 = 2.0; // envelope.min_interval [s]
/// slip.friction_coefficient, set below: the wheels declare no μ, so the node assumes it.
const MU: f64 = 0.8;
const LINEAR_FLOOR: f64 = 0.05; // envelope.linear_floor's default [m/s²]
const ANGULAR_FLOOR: f64 = 0.1; // envelope.angular_floor's default [rad/s²]
const DEAD_BAND: f64 = 0.05; // envelope.dead_band's default [-]
/// Messages received this long after a phase began carry its state: 50 Hz state, a 0.1 s tick
/// and the transport, with margin. The first phase also waits for discovery.
const SETTLE: f64 = 0.6; // [s]
const FIRST_SETTLE: f64 = 3.0; // [s]
/// The node and the test run the same solver on the same (q, v), but the node's state went
/// through `JointState`/`Odometry` and the projection onto the constraints (round-off), and
/// with the wheels' friction cones (μ assumed from `slip.friction_coefficient`) an interior-point
/// answer is exact only to the solver's tolerances (gap and feasibility 1e-10,
/// `robot_limits::program::solver_settings`): the node's solver, updated tick after tick, stops at another
/// iterate than a fresh one. Achieved 1.4e-13 with the cones (5.3e-16 without them).
const TOL: f64 = 1e-10;
/// The braking limit against its closed form: the cone program is solved to 1e-10; achieved
/// 6.0e-12 (μ 0.8), ~80× margin.
const CLOSED_TOL: f64 = 5e-10;

/// The four limits (forward acceleration, forward deceleration, yaw left, yaw right) [m/s²,
/// rad/s²], None where infeasible, and the report, from the core at a phase's state.
fn core_envelope(scene: &Scene, phase: &Value) -> ([Option<f64>; 4], EnvelopeReport) {
    let mut sys = System::from_scene(scene).expect("system");
    let model = &scene.model;
    let (mut q, mut v) = (vec![0.0; model.nq], vec![0.0; model.nv]);
    q[model.q_index("root_joint:qw").expect("qw")] = 1.0;
    let vx = model
        .v_names
        .iter()
        .position(|n| n == "root_joint:vx_local");
    v[vx.expect("vx_local")] = phase["base_forward_speed"].as_f64().unwrap();
    for (name, j) in phase["joints"].as_object().unwrap() {
        q[model.q_index(name).expect("joint")] = j["position"].as_f64().unwrap();
        let iv = model.v_names.iter().position(|n| n == name).expect("v");
        v[iv] = j["velocity"].as_f64().unwrap();
    }
    // The wheels declare no μ: the node assumes its slip.friction_coefficient.
    let em = EnvelopeModel::from_scene(scene, &sys)
        .expect("envelope model")
        .assume_friction(MU);
    let mut ed = EnvelopeData::new(&em);
    let mut elements = ForceElements::new(sys.model(), &scene.file.forces).expect("forces");
    let zero = vec![0.0; model.nv];
    let mut applied = vec![0.0; model.nv];
    applied_generalized_force(&mut sys, &mut elements, (0.0, &q, &v), &zero, &mut applied);
    acceleration_envelope(&mut sys, &em, &mut ed, &q, &v, &applied).expect("envelope");
    let report = EnvelopeReport::new(sys.model(), &em, &ed.envelope);
    let max = |l: &LimitReport| {
        assert!(
            !l.unbounded,
            "every limit of the scene is bounded or infeasible"
        );
        l.max
    };
    let four = [
        max(&report.forward_acceleration),
        max(&report.forward_deceleration),
        max(&report.yaw_acceleration_left),
        max(&report.yaw_acceleration_right),
    ];
    (four, report)
}

/// What the bridge must send while the base moves forward (docs/ros2.md): [max_accel,
/// max_decel] under the smoother's own values `own`; a limit at or below its floor, or
/// infeasible, is sent as the floor.
fn expected_smoother(l: [Option<f64>; 4], own: &Value) -> [[f64; 3]; 2] {
    let (a, d) = (&own["max_accel"], &own["max_decel"]);
    let f = |v: &Value, i: usize| v[i].as_f64().unwrap();
    let at_least = |x: Option<f64>, floor: f64| x.map_or(floor, |x| x.max(floor));
    let (fa, fd) = (at_least(l[0], LINEAR_FLOOR), at_least(l[1], LINEAR_FLOOR));
    let yaw = at_least(l[2], ANGULAR_FLOOR).min(at_least(l[3], ANGULAR_FLOOR));
    [
        [fa.min(f(a, 0)), f(a, 1), yaw.min(f(a, 2))],
        [-fd.min(-f(d, 0)), f(d, 1), -yaw.min(-f(d, 2))],
    ]
}

/// The braking limit −a [m/s²] of the floating mobile manipulator moving straight with its arm
/// at shoulder pitch `pitch` [rad] (yaw, elbow, wrist 0), when the caster lifts off: the cart's
/// closed form of docs/projection.md, −a = −g Σ mᵢxᵢ / K, K = Σ mᵢzᵢ + 2 I_w / r (moments
/// about the ground point under the axle; nothing pitches; the wheel and arm torques are
/// within their efforts). From urdf/mobile_manipulator.urdf, x forward of the axle, z above the
/// ground: chassis 8 kg at (−0.05, 0.08), wheels 2 × 0.5 kg at (0, 0.05), I_w = 0.000625
/// kg·m², r = 0.05 m, caster 0.2 kg at (−0.15, 0.025), turret 0.8 kg at (0.1, 0.18); the
/// shoulder at (0.1, 0.23) carries 0.6 kg at 0.125 m, 0.5 kg at 0.35 m, 0.3 kg at 0.5 m along
/// (sin pitch, cos pitch).
fn braking_closed_form(pitch: f64) -> f64 {
    let g = 9.81;
    let (s, c) = pitch.sin_cos();
    let arm = 0.6 * 0.125 + 0.5 * 0.35 + 0.3 * 0.5; // Σ m·l along the arm [kg·m]
    let sum_mx = 8.0 * -0.05 + 0.2 * -0.15 + 0.8 * 0.1 + 1.4 * 0.1 + arm * s;
    let sum_mz = 8.0 * 0.08 + 1.0 * 0.05 + 0.2 * 0.025 + 0.8 * 0.18 + 1.4 * 0.23 + arm * c;
    let k = sum_mz + 2.0 * 0.000625 / 0.05;
    -g * sum_mx / k
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The peer's report (the last line of its stdout), within a time limit.
fn run_peer(python: &std::path::Path) -> Value {
    peer_report(python, "envelope_peer.py", &[], Duration::from_secs(90))
}

/// The smoother's parameter sets grouped into the bridge's sends: rclpy applies a
/// `set_parameters` call one parameter at a time, and the peer records the values after each;
/// records within 50 ms are one call (sends are one tick, 0.1 s, apart at the least). Each send
/// keeps its first record's time and its last record's values.
fn sends(records: &[Value]) -> Vec<Value> {
    let mut out: Vec<Value> = Vec::new();
    for r in records {
        let t = r["t"].as_f64().unwrap();
        match out.last_mut() {
            Some(last) if t - last["t"].as_f64().unwrap() < 0.05 => {
                last["max_accel"] = r["max_accel"].clone();
                last["max_decel"] = r["max_decel"].clone();
            }
            _ => out.push(r.clone()),
        }
    }
    out
}

#[test]
#[ignore = "needs root and the peer venv: run by tools/test.sh"]
fn rclpy_reads_acceleration_limits_and_its_smoother_follows_them() {
    let _group = crate::common::exclusive_group(module_path!());
    let python = peer_python(TEST);
    if !in_namespace_or_reexec(TEST) {
        return; // the run inside the namespace passed
    }
    let rate = format!("cd_predictor:rate:={RATE}");
    let interval = format!("cd_predictor:envelope.min_interval:={MIN_INTERVAL}");
    let mut suite = SuiteProcess::spawn(
        env!("CARGO_BIN_EXE_constraint_dynamics_suite"),
        &[
            "--ros-args",
            "--params-file",
            "params/default.yaml",
            "-p",
            &format!("model.scene_file:={SCENE}"),
            "-p",
            &rate,
            "-p",
            "slip.friction_coefficient:=0.8",
            "-p",
            "cd_predictor:covariance.propagate:=false",
            "-p",
            "cd_predictor:envelope.velocity_smoother:=velocity_smoother",
            "-p",
            &interval,
            "-p",
            "cd_forces:enabled:=false",
            "-p",
            "cd_projection:enabled:=false",
            "-p",
            "cd_prediction:enabled:=false",
        ],
        "envelope_rclpy",
    );
    let report = run_peer(&python);
    let log = suite.log();
    let scene = Scene::load(repo_root().join(SCENE)).expect("scene");
    let phases = report["phases"].as_array().unwrap();
    let limits = report["limits"].as_array().unwrap();
    let sets = sends(report["sets"].as_array().unwrap());
    let own = &report["smoother_setting"];
    let t = |v: &Value| v["t"].as_f64().unwrap();
    let window = |i: usize| {
        let p = &phases[i];
        let settle = if i == 0 { FIRST_SETTLE } else { SETTLE };
        (t0(p) + settle, p["t1"].as_f64().unwrap())
    };
    fn t0(p: &Value) -> f64 {
        p["t0"].as_f64().unwrap()
    }

    // Every message of every phase's window against the core at the phase's state.
    let (mut worst, mut worst_closed) = (0.0f64, 0.0f64);
    let mut envelopes = Vec::new();
    for (i, phase) in phases.iter().enumerate() {
        let name = phase["name"].as_str().unwrap();
        let (expected, core) = core_envelope(&scene, phase);
        let (a, b) = window(i);
        let msgs: Vec<&Value> = limits.iter().filter(|m| (a..=b).contains(&t(m))).collect();
        assert!(
            !msgs.is_empty(),
            "{name}: no acceleration_limits in [{a}, {b}]\n{log}"
        );
        let bindings = [
            &core.forward_acceleration,
            &core.forward_deceleration,
            &core.yaw_acceleration_left,
            &core.yaw_acceleration_right,
        ]
        .map(|l| l.binding.iter().map(|b| b.name.clone()).collect::<Vec<_>>());
        for m in &msgs {
            assert_eq!(m["frame_id"], "base_footprint", "{name}: {m}");
            for k in 0..4 {
                let l = &m["limits"][k];
                let got = l["max"].as_f64().unwrap();
                let Some(want) = expected[k] else {
                    // INFEASIBLE, max 0 (AccelerationLimit.msg).
                    assert_eq!(
                        (&l["status"], got),
                        (&Value::from(2), 0.0),
                        "{name}: {k}: {m}"
                    );
                    continue;
                };
                assert_eq!(l["status"], 0, "{name}: limit {k} not bounded: {m}");
                let e = rel(got, want);
                worst = worst.max(e);
                assert!(
                    e <= TOL,
                    "{name}: limit {k} = {got}, core {want} (rel {e:.1e})"
                );
                let names: Vec<String> = l["binding_names"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|n| n.as_str().unwrap().to_string())
                    .collect();
                assert_eq!(names, bindings[k], "{name}: limit {k}'s binding");
            }
            // The braking limit against the closed form: the caster lifts off.
            let braking = m["limits"][1]["max"].as_f64().unwrap();
            let closed = braking_closed_form(phase["pitch"].as_f64().unwrap());
            let e = rel(braking, closed);
            worst_closed = worst_closed.max(e);
            assert!(
                e <= CLOSED_TOL,
                "{name}: braking {braking}, closed form {closed} ({e:.1e})"
            );
            assert_eq!(
                m["limits"][1]["binding_names"],
                serde_json::json!(["caster_contact"])
            );
            let unchecked: Vec<&str> = core.unchecked.iter().map(|u| u.name.as_str()).collect();
            assert_eq!(m["unchecked"][1], serde_json::json!(unchecked), "{name}");
        }
        println!(
            "{TEST}: {name} (pitch {}): {} messages; core (a_fwd, d_fwd, yaw left, right) {:?}",
            phase["pitch"],
            msgs.len(),
            expected
        );
        envelopes.push(expected);
    }
    println!(
        "{TEST}: achieved largest relative difference node vs core: {worst:.2e} (tol {TOL:.0e})"
    );
    println!(
        "{TEST}: achieved braking limit vs closed form: {worst_closed:.2e} (tol {CLOSED_TOL:.0e})"
    );
    // The physics the phases stand for (docs/projection.md): the braking limit falls as the arm
    // leans forward and is negative far forward; the small step stays inside the dead band.
    // Far forward the base cannot even hold its forward acceleration at 0, so no yaw
    // acceleration is possible with it held: the yaw limits are infeasible.
    let braking = |i: usize| envelopes[i][1].expect("braking limit bounded");
    assert!(braking(1) < braking(0) && braking(3) < 0.0, "{envelopes:?}");
    assert!(
        envelopes[3][2].is_none() && envelopes[3][3].is_none(),
        "{envelopes:?}"
    );
    for (k, (a, b)) in envelopes[2].iter().zip(&envelopes[1]).enumerate() {
        let (a, b) = (a.unwrap(), b.unwrap());
        let step = rel(a, b);
        assert!(
            step < DEAD_BAND,
            "dead_band phase moved limit {k} by {step:.3}"
        );
    }

    // The rate: the stamps' spacing (the node's timer) and the receipts over the first window.
    let (a, b) = window(0);
    let first: Vec<&Value> = limits.iter().filter(|m| (a..=b).contains(&t(m))).collect();
    let stamps: Vec<f64> = first.iter().map(|m| m["stamp"].as_f64().unwrap()).collect();
    let n = stamps.len() as f64;
    let by_stamps = (n - 1.0) / (stamps[stamps.len() - 1] - stamps[0]);
    let receipts: Vec<f64> = first.iter().map(|m| t(m)).collect();
    let by_receipts = (n - 1.0) / (receipts[receipts.len() - 1] - receipts[0]);
    println!(
        "{TEST}: achieved rate {by_stamps:.3} Hz (stamps), {by_receipts:.3} Hz (receipts over {:.1} s)",
        b - a
    );
    // A tick is computed in a few ms, so the node keeps the timer's rate (achieved 9.99–10.00
    // Hz); receipts add the transport's jitter at the window's two ends.
    assert!(
        rel(by_stamps, RATE) < 0.05,
        "rate from stamps {by_stamps} Hz"
    );
    assert!(
        rel(by_receipts, RATE) < 0.1,
        "rate from receipts {by_receipts} Hz"
    );

    // The bridge.
    let in_phase = |i: usize| -> Vec<&Value> {
        let p = &phases[i];
        let end = phases.get(i + 1).map_or(f64::INFINITY, t0);
        sets.iter()
            .filter(|s| (t0(p)..end).contains(&t(s)))
            .collect()
    };
    let check_set = |what: &str, s: &Value, want: [[f64; 3]; 2]| {
        for (key, w) in [("max_accel", want[0]), ("max_decel", want[1])] {
            let got = floats(&s[key]);
            for k in 0..3 {
                let e = if w[k] == 0.0 {
                    got[k].abs()
                } else {
                    rel(got[k], w[k])
                };
                assert!(e <= TOL, "{what}: {key} = {got:?}, want {w:?}\n{log}");
            }
        }
    };
    for s in &sets {
        println!(
            "{TEST}: smoother set at {:.3}: {} {}",
            t(s),
            s["max_accel"],
            s["max_decel"]
        );
    }
    let upright = in_phase(0);
    let last = upright
        .last()
        .unwrap_or_else(|| panic!("no set in the first phase\n{log}"));
    check_set("upright", last, expected_smoother(envelopes[0], own));
    let leaning = in_phase(1);
    assert_eq!(
        leaning.len(),
        1,
        "leaning: one tightening set expected\n{log}"
    );
    check_set("leaning", leaning[0], expected_smoother(envelopes[1], own));
    let delay = t(leaning[0]) - t0(&phases[1]);
    println!("{TEST}: achieved tightening sent {delay:.3} s after the arm leaned");
    assert!(delay < SETTLE, "tightening sent {delay} s late");
    assert!(
        in_phase(2).is_empty(),
        "a set within the dead band: {:?}",
        in_phase(2)
    );
    let far = in_phase(3);
    assert_eq!(far.len(), 1, "far forward: one set expected\n{log}");
    let want = expected_smoother(envelopes[3], own);
    assert_eq!(want[1][0], -LINEAR_FLOOR, "the floor rule itself");
    check_set("far_forward", far[0], want);
    let again = in_phase(4);
    assert_eq!(
        again.len(),
        1,
        "upright again: one loosening set expected\n{log}"
    );
    check_set(
        "upright_again",
        again[0],
        expected_smoother(envelopes[4], own),
    );
    // Back upright: a value that falls by more than the dead band is sent at once (the forward
    // acceleration, capped by the smoother's own while the arm was far forward, drops below the
    // cap as friction binds upright), one that only grows waits for min_interval.
    let gap = t(again[0]) - t(far[0]);
    let (before, after) = (
        expected_smoother(envelopes[3], own),
        expected_smoother(envelopes[4], own),
    );
    let tightens = (before.iter().flatten().zip(after.iter().flatten()))
        .any(|(b, a)| a.abs() < b.abs() * (1.0 - DEAD_BAND));
    let what = if tightens { "tightening" } else { "loosening" };
    println!(
        "{TEST}: achieved {what} sent {gap:.3} s after the last send (min_interval {MIN_INTERVAL} s)"
    );
    let expected_gap = if tightens {
        0.0..MIN_INTERVAL
    } else {
        MIN_INTERVAL..MIN_INTERVAL + 1.0
    };
    assert!(expected_gap.contains(&gap), "{what} after {gap} s");

    // /diagnostics: the four values, and a WARN while the braking limit is negative.
    let diags = report["diagnostics"].as_array().unwrap();
    let key = "forward deceleration limit [m/s²]";
    let shown = diags
        .iter()
        .filter(|d| (window(0).0..=window(0).1).contains(&t(d)))
        .filter_map(|d| d["values"][key].as_str())
        .filter_map(|s| s.split(' ').next()?.parse::<f64>().ok())
        .next_back()
        .unwrap_or_else(|| panic!("no {key:?} on /diagnostics: {diags:?}"));
    // Shown with 4 decimals.
    assert!(
        (shown - braking(0)).abs() <= 5e-5,
        "{key} = {shown}, core {}",
        braking(0)
    );
    let (fa, fb) = (t0(&phases[3]), t0(&phases[4]) + 1.0);
    assert!(
        diags.iter().any(|d| (fa..=fb).contains(&t(d))
            && d["level"] == 1
            && d["message"]
                .as_str()
                .unwrap_or("")
                .contains("forward deceleration")),
        "no WARN about the negative braking limit on /diagnostics: {:?}",
        diags
            .iter()
            .filter(|d| (fa..=fb).contains(&t(d)))
            .collect::<Vec<_>>()
    );
    assert!(
        log.contains("velocity smoother 'velocity_smoother'"),
        "{log}"
    );
    assert!(
        suite.stop(),
        "the suite did not stop cleanly:\n{}",
        suite.log()
    );
}
