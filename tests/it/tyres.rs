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

use crate::common::{assert_has, repo_dir};
use constraint_dynamics::Scene;
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

/// A scene from YAML text through a temporary file (one per call: tests run in parallel).
fn load(yaml: &str) -> constraint_dynamics::Result<Scene> {
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let path = std::env::temp_dir().join(format!(
        "tyres_{}_{}.yaml",
        std::process::id(),
        N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    std::fs::write(&path, yaml).unwrap();
    let scene = Scene::load(&path);
    let _ = std::fs::remove_file(&path);
    scene
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
    let scene = load(&yaml).unwrap();
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
        load(&format!(
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
