//! Tyres that grip by friction (`forces.tyres`, src/forces/tyre.rs) against closed forms, on the
//! diff drive of tests/data/diff_drive_centred.urdf (mass M = 9 kg, wheels r = 0.05 m with spin
//! inertia I_s = 0.000625 kg·m², centre of mass on the axle midpoint) whose wheels have no rolling
//! constraint: the base and the wheels move freely and only the tyres' friction
//! F = −μ N s/√(|s|² + s₀²) couples them (s the contact point's slip).
//!
//! - Skidding wheels: with no other horizontal force, the ground's forces on the base and the
//!   wheels' spin cancel in P = M v + 2 I_s ω / r (each tyre's force F moves M v by F and I_s ω
//!   by −F r), so P is conserved exactly and the skid ends rolling at v* = P / (M + 2 I_s/r²),
//!   whatever the friction law. While it skids, the slip mode obeys the scalar law
//!   ṡ = −μ N g(s) (r²/I_s + 2/M), g(s) = s/√(s² + s₀²), with v̇ = 2 μ N g(s)/M.
//! - Sliding sideways on still wheels: M v̇_y = −2 μ N g(v_y), the wheels never turn.

use crate::common::{assert_has, repo_dir, scene_from_yaml};
use crate::wheel_contacts::settled_twist;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::constraints::{BreakKind, ContactLimits};
use constraint_dynamics::predict::{PredictionRequest, Predictor, Trajectory};

const R: f64 = 0.05;
const I_S: f64 = 0.000625;
const MASS: f64 = 9.0;
/// A slippery floor, so the skid lasts long enough to be measured: μ 0.05, each wheel carrying
/// half the weight.
const MU: f64 = 0.05;
const SLIP_SCALE: f64 = 0.01;

fn normal_force() -> f64 {
    MASS * 9.81 / 2.0
}

fn tyre(wheel: &str, extra: &str) -> String {
    format!(
        "    - {{wheel: {wheel}, axis: [0, 1, 0], radius: {R}, friction: {MU}, normal_force: {}, \
         slip_speed_scale: {SLIP_SCALE}{extra}}}\n",
        normal_force()
    )
}

/// The centred diff drive on tyres from base velocity (vx, vy) [m/s] in its own axes and wheel
/// rates ω [rad/s] (both wheels), RK4 at 0.2 ms (the tyres' fastest rate is ≈ 930 /s).
fn sliding(vx: f64, vy: f64, w: f64, horizon: f64) -> Trajectory {
    let urdf = repo_dir().join("tests/data/diff_drive_centred.urdf");
    let yaml = format!(
        "urdf: {:?}\nbase: planar\n\
         initial_state: {{v: {{'root_joint:vx_local': {vx}, 'root_joint:vy_local': {vy}, \
         left_wheel_joint: {w}, right_wheel_joint: {w}}}}}\n\
         forces:\n  tyres:\n{}{}\
         integration: {{method: rk4, dt: 0.0002, horizon: {horizon}, sample_period: 0.05}}\n",
        urdf.display().to_string(),
        tyre("left_wheel", ""),
        tyre("right_wheel", ""),
    );
    let scene = scene_from_yaml(&yaml).unwrap();
    let mut p = Predictor::from_scene(&scene).unwrap();
    let (q, v) = (scene.q0.clone(), scene.v0.clone());
    p.predict(&PredictionRequest::new(&q, &v)).unwrap()
}

/// g(s) = s/√(s² + s₀²): the regularised sign of Coulomb friction.
fn g(s: f64) -> f64 {
    s / (s * s + SLIP_SCALE * SLIP_SCALE).sqrt()
}

/// RK4 at 1e-6 s of the scalar law `f` from x0, read at `times` (independent of the multibody
/// model).
fn scalar_law(f: impl Fn(f64) -> f64, x0: f64, times: &[f64]) -> Vec<f64> {
    let (h, mut t, mut x): (f64, f64, f64) = (1e-6, 0.0, x0);
    times
        .iter()
        .map(|&ts| {
            while t < ts - 1e-12 {
                let dt = h.min(ts - t);
                let k1 = f(x);
                let k2 = f(x + 0.5 * dt * k1);
                let k3 = f(x + 0.5 * dt * k2);
                let k4 = f(x + dt * k3);
                x += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
                t += dt;
            }
            x
        })
        .collect()
}

/// Wheels spun up on a still base skid, drag the base forward at 2 μ N/M and end rolling at
/// v* = P/(M + 2 I_s/r²), P = M v + 2 I_s ω/r conserved throughout.
#[test]
fn skidding_wheels_pull_the_base_until_they_roll_conserving_momentum() {
    let w0 = 100.0;
    let traj = sliding(0.0, 0.0, w0, 1.0);
    // Coordinates v: (vx, vy, wz) of the planar base in its own axes, then the wheels.
    let momentum = |v: &[f64]| MASS * v[0] + I_S * (v[3] + v[4]) / R;
    let p0 = 2.0 * I_S * w0 / R;
    let drift = (traj.samples.iter())
        .map(|s| (momentum(&s.v) - p0).abs() / p0)
        .fold(0.0, f64::max);
    assert!(drift < 1e-14, "P drifted by {drift:e} relative");

    // The slip mode s = r ω − v: ṡ = −μ N g(s) (r²/I_s + 2/M), from s = r ω₀ (5 m/s); the skid
    // ends near t = 5/(μ N (r²/I_s + 2/M)) = 0.536 s.
    let rate = MU * normal_force() * (R * R / I_S + 2.0 / MASS);
    let times: Vec<f64> = traj.samples.iter().map(|s| s.t).collect();
    let law = scalar_law(|s| -rate * g(s), R * w0, &times);
    let worst = (traj.samples.iter().zip(&law))
        .map(|(s, slip)| (R * s.v[3] - s.v[0] - slip).abs())
        .fold(0.0, f64::max);
    assert!(worst < 2e-10, "slip off the scalar law by {worst:e} m/s");
    // The base while skidding: v = 2 μ N t/M to within the regularisation, 1 − g(s) ≈ s₀²/2s²
    // ≤ 7e-6 while s ≥ 2.6 m/s (achieved 3.7e-6).
    let at = traj
        .samples
        .iter()
        .find(|s| (s.t - 0.25).abs() < 1e-9)
        .unwrap();
    let coulomb = 2.0 * MU * normal_force() * 0.25 / MASS;
    assert!(
        (at.v[0] - coulomb).abs() < 7e-6 * coulomb,
        "v(0.25 s) = {} against μ-limited {coulomb}",
        at.v[0]
    );
    // Rolling at the end: v* = P/(M + 2 I_s/r²) = 0.263158 m/s, the wheels at v*/r.
    let last = traj.samples.last().unwrap();
    let v_star = p0 / (MASS + 2.0 * I_S / (R * R));
    assert!(
        (last.v[0] - v_star).abs() < 1e-14,
        "{} vs {v_star}",
        last.v[0]
    );
    assert!((R * last.v[3] - v_star).abs() < 1e-14 && last.v[1].abs() < 1e-15);
}

/// A base sliding sideways on still wheels decelerates as M v̇ = −2 μ N g(v): at 2 μ N/M
/// (0.4905 m/s²) while it slides, creeping to rest; the wheels never turn and it never yaws.
#[test]
fn a_sideways_slide_stops_under_coulomb_friction() {
    let vy0 = 0.5;
    let traj = sliding(0.0, vy0, 0.0, 1.5);
    let times: Vec<f64> = traj.samples.iter().map(|s| s.t).collect();
    let a = 2.0 * MU * normal_force() / MASS;
    let law = scalar_law(|v| -a * g(v), vy0, &times);
    let mut worst: f64 = 0.0;
    for (s, vy) in traj.samples.iter().zip(&law) {
        worst = worst.max((s.v[1] - vy).abs());
        assert!(s.v[0].abs() < 1e-15 && s.v[2].abs() < 1e-15, "{:?}", s.v);
        assert!(s.v[3].abs() < 1e-15 && s.v[4].abs() < 1e-15, "{:?}", s.v);
    }
    assert!(worst < 1e-11, "v_y off the scalar law by {worst:e} m/s");
    // Coulomb's stop: 1.019 s and 0.2548 m. Below s₀ the regularised friction is viscous: 50 ms
    // later the base still creeps at 1.4e-4 m/s, and the tail adds 0.52 mm to the distance.
    let stop = vy0 / a;
    let at = traj.samples.iter().find(|s| s.t >= stop + 0.05).unwrap();
    assert!(at.v[1].abs() < 2e-4, "{}", at.v[1]);
    let y = traj.samples.last().unwrap().q[1];
    assert!((y - vy0 * vy0 / (2.0 * a)).abs() < 6e-4, "slid {y} m");
}

#[test]
fn a_bad_tyre_names_its_field() {
    let urdf = repo_dir().join("tests/data/diff_drive_centred.urdf");
    let scene = |entry: &str| {
        scene_from_yaml(&format!(
            "urdf: {:?}\nbase: planar\nforces:\n  tyres:\n{entry}",
            urdf.display().to_string()
        ))
        .and_then(|s| Predictor::from_scene(&s).map(|_| ()))
        .expect_err(entry)
        .to_string()
    };
    let e = scene(&tyre("left_wheel", "").replace("radius: 0.05", "radius: -0.05"));
    assert_has(&e, &["forces.tyres['left_wheel'].radius", "-0.05"]);
    let e = scene(&tyre("left_wheel", ", plane_normal: [0, 0, 0]"));
    assert_has(&e, &["forces.tyres['left_wheel'].plane_normal"]);
    let e = scene(&tyre("no_such_wheel", ""));
    assert_has(
        &e,
        &["forces.tyres['no_such_wheel'].wheel", "no_such_wheel"],
    );
}

/// tests/data/ball.urdf: radius [m], mass [kg], inertia about its centre [kg·m²].
const BALL_R: f64 = 0.1;
const BALL_M: f64 = 2.0;
const BALL_I: f64 = 0.4 * BALL_M * BALL_R * BALL_R;
/// The soft ground's stiffness [N/m]: the ball rests m g/k = 0.196 mm deep.
const GROUND_K: f64 = 1e5;

/// The ball on a floating base, its centre at height `z` [m] with velocity (vx, vz) [m/s], on a
/// soft ground with damping `c` [N·s/m] and friction μ; RK4 at 10 µs.
fn ball(z: f64, (vx, vz): (f64, f64), (c, mu): (f64, f64), horizon: f64) -> Trajectory {
    let urdf = repo_dir().join("tests/data/ball.urdf");
    let yaml = format!(
        "urdf: {:?}\nbase: floating\n\
         initial_state: {{q: {{'root_joint:z': {z}, 'root_joint:qw': 1.0}}, \
         v: {{'root_joint:vx_local': {vx}, 'root_joint:vz_local': {vz}}}}}\n\
         forces:\n  tyres:\n    - {{wheel: ball, radius: {BALL_R}, friction: {mu}, \
         normal_stiffness: {GROUND_K}, normal_damping: {c}, slip_speed_scale: 0.001}}\n\
         integration: {{method: rk4, dt: 1.0e-5, horizon: {horizon}, sample_period: 0.001}}\n",
        urdf.display().to_string(),
    );
    let scene = scene_from_yaml(&yaml).unwrap();
    let mut p = Predictor::from_scene(&scene).unwrap();
    let (q, v) = (scene.q0.clone(), scene.v0.clone());
    p.predict(&PredictionRequest::new(&q, &v)).unwrap()
}

/// The base's linear velocity in world axes from its twist in its own axes (q's quaternion
/// x, y, z, w at 3..7).
fn world_linear(q: &[f64], v: &[f64]) -> [f64; 3] {
    let r = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        q[6], q[3], q[4], q[5],
    ));
    (r * nalgebra::Vector3::new(v[0], v[1], v[2])).into()
}

/// A ball set sliding at v₀ on a soft floor that carries its weight: friction at the contact
/// point spins it up until it rolls at 5/7 v₀. Its angular momentum about the contact line,
/// I ω + m r v, is conserved throughout (friction acts on that line, the floor's push balances
/// the weight), and it never leaves its rest depth m g/k.
#[test]
fn a_sliding_ball_ends_rolling_at_five_sevenths_of_its_speed() {
    let v0 = 1.0;
    let rest = BALL_R - BALL_M * 9.81 / GROUND_K;
    let c = 2.0 * (GROUND_K * BALL_M).sqrt();
    let traj = ball(rest, (v0, 0.0), (c, 0.3), 0.5);
    // v: the floating base's twist in its own axes (linear, then angular); the ball turns about
    // y, so ω_y is the world's and its forward speed is R's first row times the linear part.
    let forward = |q: &[f64], v: &[f64]| world_linear(q, v)[0];
    let momentum = |q: &[f64], v: &[f64]| BALL_I * v[4] + BALL_M * BALL_R * forward(q, v);
    let l0 = BALL_M * BALL_R * v0;
    let mut drift: f64 = 0.0;
    let mut sink: f64 = 0.0;
    for s in &traj.samples {
        drift = drift.max((momentum(&s.q, &s.v) - l0).abs() / l0);
        sink = sink.max((s.q[2] - rest).abs());
    }
    assert!(drift < 1e-12, "I ω + m r v drifted by {drift:e} relative");
    assert!(sink < 1e-12, "the ball left its rest depth by {sink:e} m");
    // Sliding ends after (2/7) v₀/(μ g) = 0.0971 s; rolling at 5/7 v₀ with ω r = v.
    let last = traj.samples.last().unwrap();
    let five_sevenths = 5.0 / 7.0 * v0;
    let v_end = forward(&last.q, &last.v);
    assert!((v_end - five_sevenths).abs() < 1e-9, "{v_end}");
    assert!(
        (last.v[4] * BALL_R - five_sevenths).abs() < 1e-9,
        "{}",
        last.v[4]
    );
}

/// Dropped from 10 mm onto an undamped soft floor, the ball bounces back (one contact within the
/// 0.1 s: it lands at 45 ms and is up again 15 ms later): its energy
/// ½ m v² + m g z (+ ½ k d² while in contact) is conserved through the contact, and the contact
/// lasts (π + 2 atan(g/(ω v_i)))/ω, ω = √(k/m), v_i = √(2 g h) the impact speed.
#[test]
fn a_ball_bounces_on_an_undamped_floor_keeping_its_energy() {
    let h = 0.01;
    let traj = ball(BALL_R + h, (0.0, 0.0), (0.0, 0.3), 0.1);
    let g = 9.81;
    let energy = |q: &[f64], v: &[f64]| {
        let depth = (BALL_R - q[2]).max(0.0);
        0.5 * BALL_M * v[2] * v[2] + BALL_M * g * q[2] + 0.5 * GROUND_K * depth * depth
    };
    let e0 = energy(&traj.samples[0].q, &traj.samples[0].v);
    let worst = (traj.samples.iter())
        .map(|s| (energy(&s.q, &s.v) - e0).abs() / (BALL_M * g * h))
        .fold(0.0, f64::max);
    // RK4 at 10 µs, of first order where the floor's push sets in and ends (a kink in the
    // force): 5.7e-7 of m g h.
    assert!(worst < 1e-6, "energy moved by {worst:e} of m g h");
    let in_contact = traj.samples.iter().filter(|s| s.q[2] < BALL_R).count() as f64 * 1e-3;
    let w = (GROUND_K / BALL_M).sqrt();
    let vi = (2.0 * g * h).sqrt();
    let duration = (std::f64::consts::PI + 2.0 * (g / (w * vi)).atan()) / w;
    assert!(
        (in_contact - duration).abs() <= 1e-3,
        "{in_contact} s vs {duration} s"
    );
}

/// The centred diff drive on rolling contacts whose sideways grip is its tyres (`lateral:
/// tyre`), its PI wheel controllers holding the command (v, ω); the contacts' radius and track
/// are the controllers' own. Its yaw rate and speed are then exactly the command's, and the
/// turn's centripetal force M ω v, which only the tyres can give, makes them creep outward:
/// 2 μ N g(v_y) = −M ω v, so v_y = −f s₀/√(1 − f²) with f = M ω v/(2 μ N) (the centre of mass on
/// the axle midpoint, where both contacts lie).
fn steady_turn_with_sideways_tyres(v_cmd: f64, w_cmd: f64, contact_keys: &str) -> [f64; 3] {
    settled_twist(&sideways_tyre_drive(contact_keys), (v_cmd, w_cmd))
}

/// The centred diff drive of `steady_turn_with_sideways_tyres`, 4 s under its controllers.
fn sideways_tyre_drive(contact_keys: &str) -> constraint_dynamics::Scene {
    let urdf = repo_dir().join("tests/data/diff_drive_centred.urdf");
    let yaml = format!(
        "urdf: {:?}\nbase: planar\nconstraints:\n\
         \x20 - {{name: l, kind: rolling, wheel: left_wheel, axis: [0, 1, 0], radius: {R}{contact_keys}}}\n\
         \x20 - {{name: r, kind: rolling, wheel: right_wheel, axis: [0, 1, 0], radius: {R}{contact_keys}}}\n\
         forces:\n  tyres:\n{}{}\
         actuators:\n  diff_drive: {{left_joint: left_wheel_joint, right_joint: right_wheel_joint, \
         wheel_radius: {R}, wheel_separation: 0.34, kp: 1.0, ki: 20.0}}\n\
         integration: {{method: rk4, dt: 0.001, drift: projection, horizon: 4.0, sample_period: 0.05}}\n",
        urdf.display().to_string(),
        tyre("left_wheel", ""),
        tyre("right_wheel", ""),
    );
    scene_from_yaml(&yaml).unwrap()
}

#[test]
fn a_steady_turn_creeps_outward_as_far_as_its_centripetal_force_asks() {
    // f = 9 · 0.5 · 0.3 / (2 · 0.05 · 44.145) = 0.306 on the slippery floor: v_y ≈ −3.2 mm/s.
    for (v_cmd, w_cmd) in [(0.3, 0.5), (0.2, -0.8), (0.5, 0.15)] {
        let [vx, vy, wz] = steady_turn_with_sideways_tyres(v_cmd, w_cmd, ", lateral: tyre");
        let f = MASS * w_cmd * v_cmd / (2.0 * MU * normal_force());
        let closed = -f * SLIP_SCALE / (1.0 - f * f).sqrt();
        assert!(
            (vy - closed).abs() < 1e-14,
            "({v_cmd}, {w_cmd}): v_y {vy} against {closed} ({:e} off)",
            (vy - closed).abs()
        );
        assert!(
            (vx - v_cmd).abs() < 1e-15 && (wz - w_cmd).abs() < 5e-13,
            "{vx} {wz}"
        );
        eprintln!(
            "({v_cmd}, {w_cmd}): v_y {vy:.6e} m/s, {:.1e} off; v {:.1e}, ω {:.1e} off",
            (vy - closed).abs(),
            (vx - v_cmd).abs(),
            (wz - w_cmd).abs()
        );
    }
    // Rigid sideways (the default), the same turn does not creep at all.
    let [_, vy, _] = steady_turn_with_sideways_tyres(0.3, 0.5, "");
    assert!(vy.abs() < 1e-12, "rigid contact crept at {vy}");
    // Without a tyre on its wheel the contact would slide freely: refused, naming it.
    let urdf = repo_dir().join("tests/data/diff_drive_centred.urdf");
    let yaml = format!(
        "urdf: {:?}\nbase: planar\nconstraints:\n\
         \x20 - {{name: lonely, kind: rolling, wheel: left_wheel, axis: [0, 1, 0], radius: {R}, lateral: tyre}}\n",
        urdf.display().to_string(),
    );
    let err = Predictor::from_scene(&scene_from_yaml(&yaml).unwrap())
        .err()
        .unwrap()
        .to_string();
    assert_has(
        &err,
        &["'lonely'", "lateral: tyre", "forces.tyres", "'left_wheel'"],
    );
    let bad = yaml.replace("lateral: tyre", "lateral: soft");
    let err = scene_from_yaml(&bad).err().unwrap().to_string();
    assert_has(&err, &["'lonely'", "line 4", "soft", "`rigid` or `tyre`"]);
}

/// In that steady turn the chassis's velocity (v, v_y) turns at ω, so the base accelerates at
/// ω × (v, v_y): the rolling rows carry M ω v_y/2 each along the wheel, the tyres M ω v/2
/// sideways, and each contact uses M |ω| ‖(v, v_y)‖/(2 μ N) of its grip. The contacts' judgement
/// adds the tyre's friction to the rows' force at right angles.
#[test]
fn a_contact_held_sideways_by_its_tyre_is_judged_with_the_tyres_friction() {
    let scene = sideways_tyre_drive(", lateral: tyre");
    let mut predictor = Predictor::from_scene(&scene).unwrap();
    for (v_cmd, w_cmd) in [(0.3, 0.5), (0.4, -0.9), (0.5, -1.2)] {
        let commands = [(
            0.0,
            Command {
                base_twist: Some([v_cmd, w_cmd]),
                ..Default::default()
            },
        )];
        let limits = ContactLimits {
            friction: Some(MU),
            normal_force: Some(normal_force()),
        };
        let traj = (predictor)
            .predict(&PredictionRequest {
                commands: &commands,
                forces: true,
                contact_limits: limits,
                ..PredictionRequest::new(&scene.q0, &scene.v0)
            })
            .unwrap();
        let f = MASS * w_cmd * v_cmd / (2.0 * MU * normal_force());
        let last = traj.samples.last().unwrap();
        if f.abs() >= 1.0 {
            // f = 1.22: more than the tyres can give; the robot skids outward, and so it is judged.
            let states = last.contacts.as_ref().unwrap();
            assert!(
                states.iter().all(|s| s.breaks == Some(BreakKind::Slip)),
                "{states:?}"
            );
            continue;
        }
        let v_y = -f * SLIP_SCALE / (1.0 - f * f).sqrt();
        let along = MASS * w_cmd.abs() * v_y.abs() / 2.0;
        let tangential = MASS * w_cmd.abs() * v_cmd.hypot(v_y) / 2.0;
        for (state, lambda) in last
            .contacts
            .as_ref()
            .unwrap()
            .iter()
            .zip(last.lambda.as_ref().unwrap())
        {
            let used = state.friction_used.unwrap();
            let want = tangential / (MU * normal_force());
            println!(
                "({v_cmd}, {w_cmd}): λ {lambda:.6e} N against {along:.6e}, friction used {used} against \
                 {want} ({:.1e} off)",
                (used - want).abs()
            );
            assert!(
                (lambda.abs() - along).abs() < 2e-11,
                "{lambda} against {along}"
            );
            assert!((used - want).abs() < 1e-12, "{used} against {want}");
            assert!((state.tangential_force - tangential).abs() < 1e-12);
            assert_eq!(state.breaks, None);
        }
    }
}
