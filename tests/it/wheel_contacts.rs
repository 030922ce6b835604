//! What a scene can say of a real tyre (docs/contacts.md) against closed forms: the turning
//! resistance of wide tyres (`forces.turning_resistance`, src/forces/turning.rs), and an
//! effective rolling radius and track (a rolling contact's `radius:` and `axle_offset:`). The diff drive of tests/data/diff_drive_centred.urdf
//! (centre of mass on the axle midpoint: a spin in place stays one) spinning under constant
//! wheel torques ±τ obeys, along its spin mode (wheel rates ∓Ω b/r),
//!   a₂ Ω̇ = 2 τ b/r − 2 M_max tanh(Ω/ω₀),  a₂ = I_A + 2 I_s b²/r²,  M_max = μ N w / 4,
//! and comes to rest at Ω* = ω₀ artanh(τ b / (r M_max)) when τ b/r < M_max; above it, in the
//! Coulomb regime, Ω grows at the constant rate (2 τ b/r − 2 M_max)/a₂.

use crate::common::{assert_has, repo_dir, scene_from_yaml};
use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::algorithm::{Data, forward_kinematics};
use constraint_dynamics::forces::{ForceElements, ForcesSpec};
use constraint_dynamics::predict::{PredictionRequest, Predictor, Trajectory};

/// tests/data/diff_drive_centred.urdf: wheel radius, half track, wheel spin inertia, yaw inertia
/// about the axle midpoint (chassis 0.166666666666667 + wheels 2 (0.00035 + 0.5 · 0.17²)), mass.
const R: f64 = 0.05;
const B: f64 = 0.17;
const I_S: f64 = 0.000625;
const I_A: f64 = 0.166666666666667 + 2.0 * (0.00035 + 0.5 * 0.17 * 0.17);
const MASS: f64 = 9.0;
/// The tyres: μ, width [m], spin-rate scale [rad/s]; each wheel carries half the weight.
const MU: f64 = 0.8;
const WIDTH: f64 = 0.03;
const RATE: f64 = 0.1;

fn normal_force() -> f64 {
    MASS * 9.81 / 2.0
}
fn max_moment() -> f64 {
    MU * normal_force() * WIDTH / 4.0
}
/// a₂: the spin mode's inertia, the wheels' spin included.
fn spin_inertia() -> f64 {
    I_A + 2.0 * I_S * B * B / (R * R)
}

fn turning_yaml() -> String {
    let n = normal_force();
    format!(
        "  turning_resistance:\n\
         \x20   - {{wheel: left_wheel, width: {WIDTH}, friction: {MU}, normal_force: {n}, spin_rate_scale: {RATE}}}\n\
         \x20   - {{wheel: right_wheel, width: {WIDTH}, friction: {MU}, normal_force: {n}, spin_rate_scale: {RATE}}}\n"
    )
}

const CONTACTS: &str = "constraints:
  - {name: left_wheel_contact, kind: rolling, wheel: left_wheel, axis: [0, 1, 0], radius: 0.05}
  - {name: right_wheel_contact, kind: rolling, wheel: right_wheel, axis: [0, 1, 0], radius: 0.05}
";

/// The centred diff drive spinning at `w0` [rad/s] under wheel torques (left, right) [N·m],
/// with or without the turning resistance, RK4 at 1 ms.
fn centred(w0: f64, (left, right): (f64, f64), turning: bool, horizon: f64) -> Trajectory {
    let urdf = repo_dir().join("tests/data/diff_drive_centred.urdf");
    let wheel = w0 * B / R;
    let yaml = format!(
        "urdf: {:?}\nbase: planar\n\
         initial_state: {{v: {{'root_joint:wz': {w0}, left_wheel_joint: {}, right_wheel_joint: {wheel}}}}}\n\
         {CONTACTS}forces:\n  joint_torques:\n\
         \x20   - {{joint: left_wheel_joint, value: {left}}}\n\
         \x20   - {{joint: right_wheel_joint, value: {right}}}\n{}\
         integration: {{method: rk4, dt: 0.001, drift: projection, horizon: {horizon}, sample_period: 0.01}}\n",
        urdf.display().to_string(),
        -wheel,
        if turning {
            turning_yaml()
        } else {
            String::new()
        }
    );
    let scene = scene_from_yaml(&yaml).unwrap();
    let mut p = Predictor::from_scene(&scene).unwrap();
    let (q, v) = (scene.q0.clone(), scene.v0.clone());
    p.predict(&PredictionRequest::new(&q, &v)).unwrap()
}

/// Ω(t) of the scalar law by RK4 at 1e-5 s (independent of the predictor's multibody model).
fn spin_law(w0: f64, tau: f64, times: &[f64]) -> Vec<f64> {
    let f = |w: f64| (2.0 * tau * B / R - 2.0 * max_moment() * (w / RATE).tanh()) / spin_inertia();
    let (h, mut t, mut w): (f64, f64, f64) = (1e-5, 0.0, w0);
    let mut out = Vec::with_capacity(times.len());
    for &ts in times {
        while t < ts - 1e-12 {
            let dt = h.min(ts - t);
            let k1 = f(w);
            let k2 = f(w + 0.5 * dt * k1);
            let k3 = f(w + 0.5 * dt * k2);
            let k4 = f(w + dt * k3);
            w += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            t += dt;
        }
        out.push(w);
    }
    out
}

/// Constant torques below the Coulomb moment: the spin creeps up to Ω* = ω₀ artanh(τ b/(r M_max))
/// and follows the scalar law on the way; it stays a spin in place.
#[test]
fn a_spin_under_constant_torques_settles_where_the_motors_balance_the_scrub() {
    // τ b/r = 0.17 N·m against M_max = 0.2649 N·m: ratio 0.642, Ω* = 0.0762 rad/s, settling
    // rate 2 M_max sech²/(ω₀ a₂) = 14.8 /s.
    let tau = 0.05;
    let traj = centred(0.0, (-tau, tau), true, 1.5);
    let wz = |s: &constraint_dynamics::predict::Sample| s.v[2];
    let times: Vec<f64> = traj.samples.iter().map(|s| s.t).collect();
    let law = spin_law(0.0, tau, &times);
    let worst = (traj.samples.iter().zip(&law))
        .map(|(s, w)| (wz(s) - w).abs())
        .fold(0.0, f64::max);
    let steady = RATE * (tau * B / (R * max_moment())).atanh();
    let last = traj.samples.last().unwrap();
    let forward = (traj.samples.iter())
        .map(|s| s.v[0].abs().max(s.v[1].abs()))
        .fold(0.0, f64::max);
    println!(
        "achieved spin vs the scalar law: {worst:.3e} rad/s; final {} vs Ω* {steady} rad/s; \
         max |vx|, |vy| {forward:.1e} m/s",
        wz(last)
    );
    // Achieved 5.5e-11 rad/s (RK4 at 1 ms on a 14.8 /s mode), 1.6e-10 relative to Ω* at 1.5 s
    // (e^-22 of the transient left), 6.5e-18 m/s.
    assert!(worst < 1e-9, "{worst}");
    assert!((wz(last) - steady).abs() < 5e-9 * steady, "{}", wz(last));
    assert!(forward < 1e-16, "{forward}");
}

/// Above the Coulomb moment the spin accelerates at the constant rate (2 τ b/r − 2 M_max)/a₂
/// (tanh(Ω/ω₀) = 1 to 1e-17 for Ω ≥ 2 rad/s).
#[test]
fn above_the_coulomb_moment_the_spin_accelerates_at_the_constant_rate() {
    let tau = 1.5 * max_moment() * R / B;
    let traj = centred(2.0, (-tau, tau), true, 0.5);
    let rate = (2.0 * tau * B / R - 2.0 * max_moment()) / spin_inertia();
    let worst = (traj.samples.iter())
        .map(|s| (s.v[2] - (2.0 + rate * s.t)).abs())
        .fold(0.0, f64::max);
    println!("achieved spin vs 2 + {rate} t: {worst:.3e} rad/s");
    // Achieved 1.0e-13 rad/s: Ω is linear in t, which RK4 integrates exactly (rounding over
    // 500 steps).
    assert!(worst < 2e-12, "{worst}");
}

/// Straight ahead the wheels do not spin about the normal: equal torques drive the same with
/// or without the turning resistance.
#[test]
fn a_straight_drive_is_unaffected() {
    let a = centred(0.0, (0.2, 0.2), true, 1.0);
    let b = centred(0.0, (0.2, 0.2), false, 1.0);
    let worst = (a.samples.iter().zip(&b.samples))
        .flat_map(|(x, y)| x.q.iter().zip(&y.q).chain(x.v.iter().zip(&y.v)))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    let speed = a.samples.last().unwrap().v[0];
    println!("achieved straight drive difference {worst:.1e} (forward speed {speed} m/s)");
    // Achieved exactly 0: the yaw rate stays 0 and tanh(0) = 0.
    assert!(speed > 0.5, "{speed}");
    assert!(worst < 1e-15, "{worst}");
}

/// At any state the element's generalized force on the planar base is −M_max tanh(ω_z/ω₀) per
/// wheel on the yaw coordinate alone (the wheel axles are horizontal), and its power is ≤ 0.
#[test]
fn the_scrub_moment_acts_on_the_yaw_and_only_dissipates() {
    let scene = centred_scene_without_torques();
    let model = &scene.model;
    let spec: ForcesSpec = serde_yaml::from_str(&turning_yaml()).unwrap();
    let mut elements = ForceElements::new(model, &spec).unwrap();
    let mut data = Data::new(model);
    let zero = vec![0.0; model.nv];
    let mut rng = 0x2545f4914f6cdd1du64;
    let mut uniform = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut worst: f64 = 0.0;
    for _ in 0..200 {
        let q: Vec<f64> = (0..model.nq).map(|_| 3.0 * uniform()).collect();
        let v: Vec<f64> = (0..model.nv).map(|_| uniform()).collect();
        forward_kinematics(model, &mut data, &q, &v, &zero);
        let mut tau = vec![0.0; model.nv];
        elements.add_generalized_force(model, &data, 0.0, &q, &v, &mut tau);
        let mut want = vec![0.0; model.nv];
        want[2] = -2.0 * max_moment() * (v[2] / RATE).tanh();
        for (a, b) in tau.iter().zip(&want) {
            worst = worst.max((a - b).abs());
        }
        let power: f64 = tau.iter().zip(&v).map(|(t, x)| t * x).sum();
        assert!(power <= 0.0, "power {power} at v {v:?}");
    }
    println!("achieved generalized force vs −2 M_max tanh(ω_z/ω₀) e_yaw: {worst:.1e} N·m");
    assert!(worst < 1e-15, "{worst}");
}

fn centred_scene_without_torques() -> Scene {
    let urdf = repo_dir().join("tests/data/diff_drive_centred.urdf");
    scene_from_yaml(&format!(
        "urdf: {:?}\nbase: planar\n{CONTACTS}",
        urdf.display().to_string()
    ))
    .unwrap()
}

/// Under the bundled diff drive's PI wheel controllers (urdf/diff_drive.urdf, URDF damping
/// d = 0.01 N·m·s/rad) a commanded spin at Ω is held, and the wheels' antisymmetric torque at
/// the steady spin is what the spin mode's balance says: (τ_R − τ_L)/2 = d Ω b/r + M_max
/// tanh(Ω/ω₀) r/b (the symmetric part holds the offset centre of mass on its circle).
#[test]
fn controllers_holding_a_spin_pay_the_scrub_moment() {
    let urdf = repo_dir().join("urdf/diff_drive.urdf");
    let yaml = format!(
        "urdf: {:?}\nbase: planar\n{CONTACTS}forces:\n  urdf_damping: true\n{}\
         actuators:\n  control_period: 0.001\n  diff_drive: {{left_joint: left_wheel_joint, \
         right_joint: right_wheel_joint, wheel_radius: 0.05, wheel_separation: 0.34, kp: 1.0, \
         ki: 20.0}}\n\
         integration: {{method: rk4, dt: 0.001, drift: projection, horizon: 3.0, sample_period: 0.02}}\n",
        urdf.display().to_string(),
        turning_yaml()
    );
    let scene = scene_from_yaml(&yaml).unwrap();
    let mut p = Predictor::from_scene(&scene).unwrap();
    let omega = 1.0;
    let commands = [(
        0.0,
        Command {
            base_twist: Some([0.0, omega]),
            ..Default::default()
        },
    )];
    let (q, v) = (scene.q0.clone(), scene.v0.clone());
    let traj = p
        .predict(&PredictionRequest {
            commands: &commands,
            ..PredictionRequest::new(&q, &v)
        })
        .unwrap();
    let last = traj.samples.last().unwrap();
    let (tl, tr) = (last.actuator_torque[3], last.actuator_torque[4]);
    let want = 0.01 * omega * B / R + max_moment() * (omega / RATE).tanh() * R / B;
    println!(
        "achieved spin {} rad/s; antisymmetric torque {} vs {want} N·m",
        last.v[2],
        (tr - tl) / 2.0
    );
    // Achieved 2.5e-14 rad/s and 1.4e-15 N·m at 3 s: the PI's integral has settled.
    assert!((last.v[2] - omega).abs() < 1e-12, "{}", last.v[2]);
    assert!(((tr - tl) / 2.0 - want).abs() < 1e-13, "{tl} {tr}");
}

/// A bad entry names its wheel and field; an unknown frame names the frame.
#[test]
fn a_bad_turning_resistance_names_its_field() {
    let urdf = repo_dir().join("tests/data/diff_drive_centred.urdf");
    let with = |entry: &str| {
        scene_from_yaml(&format!(
            "urdf: {:?}\nbase: planar\n{CONTACTS}forces:\n  turning_resistance:\n    - {entry}\n",
            urdf.display().to_string()
        ))
        .and_then(|s| constraint_dynamics::System::from_scene(&s).map(|_| s))
        .and_then(|s| Predictor::from_scene(&s).map(|_| ()))
        .expect_err(entry)
        .to_string()
    };
    let e = with("{wheel: left_wheel, width: -0.03, friction: 0.8, normal_force: 44}");
    assert_has(
        &e,
        &["forces.turning_resistance['left_wheel'].width", "-0.03"],
    );
    let e = with("{wheel: left_wheel, width: 0.03, friction: 0.8, normal_force: .nan}");
    assert_has(&e, &["turning_resistance['left_wheel'].normal_force"]);
    let e = with(
        "{wheel: left_wheel, width: 0.03, friction: 0.8, normal_force: 44, spin_rate_scale: 0}",
    );
    assert_has(&e, &["spin_rate_scale"]);
    let e = with("{wheel: no_such_wheel, width: 0.03, friction: 0.8, normal_force: 44}");
    assert_has(
        &e,
        &["turning_resistance['no_such_wheel'].wheel", "no_such_wheel"],
    );
    let e = with("{wheel: left_wheel, width: 0.03, friction: 0.8}");
    assert_has(&e, &["normal_force"]);
    let e = with("{wheel: left_wheel, width: 0.03, friction: 0.8, normal_force: 44, mu: 1}");
    assert_has(&e, &["mu"]);
}

/// The bundled diff drive under its PI wheel-speed controllers (nominal r = 0.05 m, b = 0.17 m)
/// with both contacts at the effective radius `r_eff` and the keys `left` / `right` added to
/// their rolling contacts.
fn effective_diff_drive(r_eff: f64, left: &str, right: &str) -> String {
    let urdf = repo_dir().join("urdf/diff_drive.urdf");
    format!(
        "urdf: {:?}\nbase: planar\nconstraints:\n\
         \x20 - {{name: l, kind: rolling, wheel: left_wheel, axis: [0, 1, 0], radius: {r_eff}, {left}}}\n\
         \x20 - {{name: r, kind: rolling, wheel: right_wheel, axis: [0, 1, 0], radius: {r_eff}, {right}}}\n\
         forces: {{urdf_damping: true}}\n\
         actuators:\n  control_period: 0.001\n  diff_drive: {{left_joint: left_wheel_joint, \
         right_joint: right_wheel_joint, wheel_radius: 0.05, wheel_separation: 0.34, kp: 1.0, \
         ki: 20.0}}\n\
         integration: {{method: rk4, dt: 0.001, drift: projection, horizon: 3.0, sample_period: 0.02}}\n",
        urdf.display().to_string(),
    )
}

/// The planar base's twist in its own axes, (forward, sideways [m/s], yaw rate [rad/s]), at the
/// scene's horizon under the command (v, ω) from its initial state.
pub(crate) fn settled_twist(
    scene: &constraint_dynamics::Scene,
    (v_cmd, w_cmd): (f64, f64),
) -> [f64; 3] {
    let commands = [(
        0.0,
        Command {
            base_twist: Some([v_cmd, w_cmd]),
            ..Default::default()
        },
    )];
    let (q, v) = (scene.q0.clone(), scene.v0.clone());
    let traj = Predictor::from_scene(scene)
        .unwrap()
        .predict(&PredictionRequest {
            commands: &commands,
            ..PredictionRequest::new(&q, &v)
        })
        .unwrap();
    let last = traj.samples.last().unwrap();
    [last.v[0], last.v[1], last.v[2]]
}

/// With the contacts at an effective radius r' and half-track b' (`axle_offset` ±s outward)
/// the robot goes at v r'/r and turns at ω (r'/r)(b/b'), the wheels at their targets.
#[test]
fn an_effective_radius_and_track_scale_what_the_controllers_achieve() {
    let (r_eff, s) = (0.049, 0.01);
    let yaml = effective_diff_drive(
        r_eff,
        &format!("axle_offset: {s}"),
        &format!("axle_offset: {}", -s),
    );
    let scene = scene_from_yaml(&yaml).unwrap();
    let (v_cmd, w_cmd) = (0.4, 0.8);
    let [v, _, w] = settled_twist(&scene, (v_cmd, w_cmd));
    let speed = v_cmd * r_eff / R;
    let turn = w_cmd * (r_eff / R) * B / (B + s);
    println!("achieved v {v} vs {speed} m/s, ω {w} vs {turn} rad/s");
    // Achieved 2.6e-15 m/s and 2.0e-13 rad/s: the PI's integral has settled by 3 s.
    assert!((v - speed).abs() < 1e-12, "{v}");
    assert!((w - turn).abs() < 1e-12, "{w}");
    let bad = scene_from_yaml(&yaml.replace("axle_offset: 0.01}", "axle_offset: .inf}"))
        .and_then(|s| constraint_dynamics::System::from_scene(&s).map(|_| ()))
        .expect_err("an infinite offset")
        .to_string();
    assert_has(&bad, &["axle_offset", "'l'"]);
}

/// `axle_offset_turn_gain: k` widens the half-track to b' = b + s₀ + k Ω² at the turn rate Ω.
/// Under the controllers' wheel targets the steady turn then solves
/// Ω (b + s₀ + k Ω²) = ω (r'/r) b, a cubic (Newton here), and the speed is v r'/r as before.
#[test]
fn a_turn_gain_widens_the_track_with_the_turn_rate() {
    let (r_eff, s0, k) = (0.049, 0.002, 0.004);
    let yaml = effective_diff_drive(
        r_eff,
        &format!("axle_offset: {s0}, axle_offset_turn_gain: {k}"),
        &format!("axle_offset: {}, axle_offset_turn_gain: {}", -s0, -k),
    );
    let scene = scene_from_yaml(&yaml).unwrap();
    for (v_cmd, w_cmd) in [(0.0, 1.5), (0.3, -1.0), (0.4, 0.3)] {
        let [v, _, w] = settled_twist(&scene, (v_cmd, w_cmd));
        let rhs = w_cmd * (r_eff / R) * B;
        let mut turn = rhs / B;
        for _ in 0..50 {
            let f = turn * (B + s0 + k * turn * turn) - rhs;
            turn -= f / (B + s0 + 3.0 * k * turn * turn);
        }
        let speed = v_cmd * r_eff / R;
        println!("achieved v {v} vs {speed} m/s, ω {w} vs {turn} rad/s");
        // Achieved ≤ 7.9e-15 m/s and ≤ 1.6e-13 rad/s: the PI's integral has settled by 3 s.
        assert!((v - speed).abs() < 1e-12, "{v}");
        assert!((w - turn).abs() < 1e-12, "{w} vs {turn}");
    }
    // The contact point moves with the turn rate only through the drift control.
    let none = scene_from_yaml(&yaml.replace("drift: projection", "drift: none")).unwrap();
    let (q, v) = (none.q0.clone(), none.v0.clone());
    let e = Predictor::from_scene(&none)
        .unwrap()
        .predict(&PredictionRequest::new(&q, &v))
        .expect_err("a turn gain without drift control")
        .to_string();
    assert_has(&e, &["'l'", "axle_offset_turn_gain", "drift"]);
    let bad = scene_from_yaml(&yaml.replace(
        &format!("axle_offset_turn_gain: {k}}}"),
        "axle_offset_turn_gain: .nan}",
    ))
    .and_then(|s| constraint_dynamics::System::from_scene(&s).map(|_| ()))
    .expect_err("a NaN turn gain")
    .to_string();
    assert_has(&bad, &["axle_offset_turn_gain", "'l'"]);
}
