//! Process noise against its closed forms on a 2 kg slider (a prismatic joint along x, no
//! gravity along it) under a velocity controller (kp 4 N·s/m, no integral, effort 1 N):
//! - asked for 10 m/s it saturates for the whole second: the force is a constant 1 N, white
//!   acceleration noise of density σ (`acceleration_noise`) gives the double integrator's
//!   `σ² [t³/3, t²/2; t²/2, t]`, and an acceleration offset of standard deviation σ_b while
//!   saturated (`saturation_bias`) adds a constant acceleration's `σ_b² [t⁴/4, t³/2; t³/2, t²]`,
//!   and a rate offset of standard deviation σ_k on its position while saturated
//!   (`saturation_slip`) a constant rate's `σ_k² t²` on the position alone;
//! - asked for 0.2 m/s it stays inside its effort (kp·0.2 = 0.8 N): v is an Ornstein–Uhlenbeck
//!   process of rate a = kp/m, `var v(t) = σ² (1 − e^{−2at}) / (2a)` (to (aH)²/6 for chunks of
//!   H), and σ_b adds nothing;
//! - asked for 0.3 m/s from rest it asks kp·0.3 = 1.2 N, is held at 1 N until kp (0.3 − v) = 1 N,
//!   v = 0.05 m/s at 1 N / 2 kg: saturated for 0.1 s (`Trajectory::saturated_s`), and the
//!   slide's variance stops there at `σ_k² (0.1 s)²`.
//!
//! And on the bundled mobile manipulator through a skid, every term's share superposes.

use crate::common;
use common::*;
use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use nalgebra::DMatrix;

const URDF: &str = r#"<?xml version="1.0"?>
<robot name="slider">
  <link name="rail"/>
  <link name="carriage"><inertial><mass value="2.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="slider" type="prismatic"><parent link="rail"/><child link="carriage"/>
    <axis xyz="1 0 0"/><limit lower="-100" upper="100" effort="1.0" velocity="20"/></joint>
</robot>
"#;
const MASS_KG: f64 = 2.0;
const KP: f64 = 4.0;
const SIGMA: f64 = 0.3;
const SIGMA_BIAS: f64 = 0.4;
const SIGMA_SLIDE: f64 = 0.05;

/// The slider with every process-noise term.
fn slider(hold: &str) -> Scene {
    let terms = format!(
        "acceleration_noise: {{ slider: {SIGMA} }}, saturation_bias: {{ slider: {SIGMA_BIAS} }}, \
         saturation_slip: {{ slider: {SIGMA_SLIDE} }}"
    );
    slider_with(hold, &terms)
}

/// The slider with `uncertainty: {terms}`.
fn slider_with(hold: &str, terms: &str) -> Scene {
    let yaml = format!(
        "urdf: slider.urdf\nbase: fixed\ngravity: [0.0, 0.0, -9.81]\n\
         actuators:\n  hold: {hold}\n  velocity:\n    - {{ joint: slider, kp: {KP}, ki: 0.0 }}\n\
         integration:\n  method: rk4\n  dt: 0.001\n\
         uncertainty: {{ {terms} }}\n"
    );
    scene_with_urdf("slider", URDF, &yaml)
}

/// (t [s], [[P_qq, P_qv], [P_vq, P_vv]]) at a sample.
type CovarianceAt = (f64, [[f64; 2]; 2]);

/// The covariance at every sample of a 1 s prediction from rest asked for `target` [m/s], and
/// the time it spent saturated [s].
fn covariances(scene: &Scene, target: f64) -> (Vec<CovarianceAt>, f64) {
    let mut pred = Predictor::from_scene(scene)
        .unwrap()
        .with_settings(|s| s.error_estimate = false)
        .unwrap();
    let cmd = Command {
        joint_velocity: [("slider".to_string(), target)].into(),
        ..Default::default()
    };
    let p0 = DMatrix::zeros(2, 2);
    let commands = [(0.0, cmd)];
    let req = PredictionRequest::new(&[0.0], &[0.0])
        .horizon(1.0)
        .commands(&commands)
        .covariance(&p0);
    let traj = pred.predict(&req).unwrap();
    let samples = (traj.samples.iter())
        .filter(|s| s.t > 0.0)
        .map(|s| {
            let p = rows_to_matrix(s.covariance.as_ref().unwrap());
            (s.t, [[p[(0, 0)], p[(0, 1)]], [p[(1, 0)], p[(1, 1)]]])
        })
        .collect();
    (samples, traj.saturated_s)
}

#[test]
fn saturation_bias_is_a_constant_acceleration_while_saturated() {
    for hold in ["continuous", "zero_order"] {
        let mut worst: f64 = 0.0;
        let (samples, saturated_s) = covariances(&slider(hold), 10.0);
        for (t, p) in samples {
            let (s2, b2) = (SIGMA * SIGMA, SIGMA_BIAS * SIGMA_BIAS);
            let k2 = SIGMA_SLIDE * SIGMA_SLIDE;
            let exact = [
                [
                    s2 * t.powi(3) / 3.0 + b2 * t.powi(4) / 4.0 + k2 * t * t,
                    s2 * t * t / 2.0 + b2 * t.powi(3) / 2.0,
                ],
                [s2 * t * t / 2.0 + b2 * t.powi(3) / 2.0, s2 * t + b2 * t * t],
            ];
            for a in 0..2 {
                for b in 0..2 {
                    worst = worst.max((p[a][b] - exact[a][b]).abs() / exact[a][b]);
                }
            }
        }
        println!("{hold}: saturated {saturated_s} s, worst relative difference {worst:.2e}");
        assert!(worst < 1e-12, "{hold}: {worst:e}");
        assert!((saturated_s - 1.0).abs() < 1e-12, "{hold}: {saturated_s}");
    }
}

#[test]
fn saturated_time_ends_where_the_controller_comes_inside_its_effort() {
    // Saturated until v = 0.3 − 1 N / kp = 0.05 m/s, reached at 1 N / 2 kg in 0.1 s; the held
    // controller sees it at its next tick (the scene's control period, 1 ms by default).
    let exact = (0.3 - 1.0 / KP) / (1.0 / MASS_KG);
    for (hold, tol) in [("continuous", 1e-6), ("zero_order", 1.001e-3)] {
        let (_, saturated_s) = covariances(&slider(hold), 0.3);
        println!("{hold}: saturated {saturated_s:.6} s (exact {exact} s)");
        assert!((saturated_s - exact).abs() <= tol, "{hold}: {saturated_s}");
    }
}

#[test]
fn the_skids_slide_stops_with_the_saturation() {
    // Only the slide: var q = σ_k² min(t, t_s)², t_s = 0.1 s as above; v never sees it.
    let terms = format!("saturation_slip: {{ slider: {SIGMA_SLIDE} }}");
    for hold in ["continuous", "zero_order"] {
        let (samples, saturated_s) = covariances(&slider_with(hold, &terms), 0.3);
        let mut worst: f64 = 0.0;
        for (t, p) in &samples {
            let exact = (SIGMA_SLIDE * t.min(saturated_s)).powi(2);
            worst = worst.max((p[0][0] - exact).abs() / exact);
            assert!(
                p[1][1].abs() < 1e-15 && p[0][1].abs() < 1e-15,
                "{hold} t {t}: {p:?}"
            );
        }
        println!("{hold}: saturated {saturated_s:.6} s, worst relative difference {worst:.2e}");
        assert!(worst < 1e-12, "{hold}: {worst:e}");
    }
    // A coordinate the robot does not have is refused, naming the field and the name.
    let mut pred =
        Predictor::from_scene(&slider_with("continuous", "saturation_slip: { x: 0.1 }")).unwrap();
    let p0 = DMatrix::zeros(2, 2);
    let e = (pred.predict(&PredictionRequest::new(&[0.0], &[0.0]).covariance(&p0))).unwrap_err();
    assert!(
        e.to_string()
            .contains("uncertainty.saturation_slip: unknown velocity coordinate 'x'"),
        "{e}"
    );
}

#[test]
fn saturation_bias_is_absent_inside_the_effort() {
    let a = KP / MASS_KG;
    for hold in ["continuous", "zero_order"] {
        let (samples, saturated_s) = covariances(&slider(hold), 0.2);
        assert_eq!(saturated_s, 0.0, "{hold}");
        // Over a chunk of H the noise enters through the chunk's own transition taken linear
        // in time (docs/propagation.md): with A = e^{−aH} on v, δ = A − 1, the chunk adds
        // Q = σ² H ((1 + δ/2)² + δ²/12) and P_vv(kH) = Q (1 − A^{2k}) / (1 − A²), which is the
        // Ornstein–Uhlenbeck variance σ² (1 − e^{−2at}) / (2a) to a relative (aH)²/6.
        let h = samples[0].0;
        let damping = (-a * h).exp();
        let delta = damping - 1.0;
        let q = SIGMA * SIGMA * h * ((1.0 + delta / 2.0).powi(2) + delta * delta / 12.0);
        let (mut discrete, mut continuous): (f64, f64) = (0.0, 0.0);
        for (t, p) in &samples {
            let k = (t / h).round() as i32;
            let chunked = q * (1.0 - damping.powi(2 * k)) / (1.0 - damping * damping);
            let ou = SIGMA * SIGMA * (1.0 - (-2.0 * a * t).exp()) / (2.0 * a);
            discrete = discrete.max((p[1][1] - chunked).abs() / chunked);
            continuous = continuous.max((p[1][1] - ou).abs() / ou);
        }
        println!(
            "{hold}: inside the effort, var v against the chunked form {discrete:.2e}, \
             against the Ornstein–Uhlenbeck variance {continuous:.2e} ((aH)²/6 = {:.2e})",
            (a * h).powi(2) / 6.0
        );
        assert!(discrete < 5e-9, "{hold}: {discrete:e}");
        assert!(
            continuous < 1.01 * (a * h).powi(2) / 6.0,
            "{hold}: {continuous:e}"
        );
    }
}

/// Slip noise of density σ_s on the diff drive's yaw (`uncertainty.slip_noise`) while it drives
/// straight along x: the yaw is a random walk, var ψ = σ_s² t, and every yaw slip at s turns
/// the rest of the path, δy(T) = (x(T) − x(s)) δψ(s), so var y = σ_s² ∫₀ᵀ (x(T) − x(s))² ds
/// and cov(y, ψ) = σ_s² ∫₀ᵀ (x(T) − x(s)) ds (u² T³/3 and u T²/2 at a constant speed u),
/// taken over the predicted path. The wheel speeds and the velocity block never see it.
#[test]
fn yaw_slip_noise_is_a_random_walk_that_turns_the_path() {
    const SLIP: f64 = 0.01;
    const U: f64 = 0.5;
    let path = repo_dir().join("params/suite_diff_drive.yaml");
    let urdf = repo_dir().join("urdf/diff_drive.urdf");
    let yaml = std::fs::read_to_string(&path).unwrap().replace(
        "urdf: ../urdf/diff_drive.urdf",
        &format!("urdf: {:?}", urdf.display().to_string()),
    ) + &format!("uncertainty:\n  slip_noise: {{ root_joint:wz: {SLIP} }}\n");
    let scene = scene_from_yaml(&yaml).unwrap();
    let m = scene.model.clone();
    let (nv, wheel_speed) = (m.nv, U / 0.05);
    let mut v = vec![0.0; nv];
    v[m.v_index("root_joint:vx_local").unwrap()] = U;
    v[m.v_index("left_wheel_joint").unwrap()] = wheel_speed;
    v[m.v_index("right_wheel_joint").unwrap()] = wheel_speed;
    let q = m.neutral();
    let mut pred = Predictor::from_scene(&scene)
        .unwrap()
        .with_settings(|s| s.error_estimate = false)
        .unwrap();
    let cmd = Command {
        base_twist: Some([U, 0.0]),
        ..Default::default()
    };
    let commands = [(0.0, cmd)];
    let p0 = DMatrix::zeros(2 * nv, 2 * nv);
    let req = PredictionRequest::new(&q, &v)
        .horizon(2.0)
        .commands(&commands)
        .covariance(&p0);
    let traj = pred.predict(&req).unwrap();
    let (ix, iy, iyaw) = (0, 1, 2);
    let x: Vec<(f64, f64)> = (traj.samples.iter()).map(|s| (s.t, s.q[ix])).collect();
    let s2 = SLIP * SLIP;
    let mut worst: f64 = 0.0;
    for (k, s) in traj.samples.iter().enumerate().skip(1) {
        let p = rows_to_matrix(s.covariance.as_ref().unwrap());
        // ∫ (x(T) − x(s))ⁿ ds, n = 1, 2, with x linear between the 20 ms samples:
        // (a + b)/2 and (a² + ab + b²)/3 per interval.
        let moment = |n: i32| -> f64 {
            (x[..=k].windows(2))
                .map(|w| {
                    let (a, b) = (s.q[ix] - w[0].1, s.q[ix] - w[1].1);
                    let mean = if n == 1 {
                        (a + b) / 2.0
                    } else {
                        (a * a + a * b + b * b) / 3.0
                    };
                    mean * (w[1].0 - w[0].0)
                })
                .sum()
        };
        let exact = [
            (p[(iyaw, iyaw)], s2 * s.t),
            (p[(iy, iyaw)], s2 * moment(1)),
            (p[(iy, iy)], s2 * moment(2)),
        ];
        // Over the first 0.1 s the wheels' PI builds the torque the URDF damping takes and
        // the speed dips by 0.5 %, which the linear interpolation of x does not resolve.
        for (got, want) in exact.into_iter().filter(|_| s.t >= 0.1) {
            worst = worst.max((got - want).abs() / want);
        }
        // Rounding in the constraint projection: 1e-10 of the pose's variances.
        for i in nv..2 * nv {
            let scale = 1e-10 * p[(iy, iy)];
            assert!(
                p[(i, i)].abs() < scale,
                "t {}: P_vv[{i}] = {:e}",
                s.t,
                p[(i, i)]
            );
        }
    }
    let last = traj.samples.last().unwrap();
    let p = rows_to_matrix(last.covariance.as_ref().unwrap());
    let u = last.q[ix] / last.t;
    println!(
        "worst relative difference {worst:.2e}; at {} s var y {:.4e} (constant speed: {:.4e})",
        last.t,
        p[(iy, iy)],
        s2 * u * u * last.t.powi(3) / 3.0
    );
    assert!(worst < 1e-3, "{worst:e}");
}

/// The calibration sizes the noise terms from one prediction per term
/// (src/calibrate/noise_basis.rs): that rests on superposition, each term's variance adding
/// its own share to the covariance along the nominal trajectory. On the bundled mobile
/// manipulator driving off hard enough to skid (the diff drive saturated at its traction
/// torque), the covariance with every term equals the one without process noise plus what
/// each term adds alone, to rounding.
#[test]
fn noise_terms_add_their_shares_independently() {
    let scene = Scene::load(repo_dir().join("params/suite_mobile_manipulator.yaml")).unwrap();
    // (field, coordinate, σ)
    let terms = [
        ("effort_noise", "left_wheel_joint", 0.05),
        ("acceleration_noise", "right_wheel_joint", 30.0),
        ("saturation_bias", "right_wheel_joint", 3000.0),
        ("saturation_slip", "root_joint:vx_local", 0.05),
        ("saturation_slip", "root_joint:wz", 0.2),
        ("slip_noise", "root_joint:wz", 0.01),
    ];
    let mut cmd = turning_with_arm_held();
    cmd.base_twist = Some([1.0, 2.0]);
    let commands = [(0.0, cmd)];
    let covariance = |which: &[usize]| {
        let mut scene = scene.clone();
        let u = &mut scene.file.uncertainty;
        for &i in which {
            let (field, coordinate, sigma) = terms[i];
            let map = match field {
                "effort_noise" => &mut u.effort_noise,
                "acceleration_noise" => &mut u.acceleration_noise,
                "saturation_bias" => &mut u.saturation_bias,
                "saturation_slip" => &mut u.saturation_slip,
                _ => &mut u.slip_noise,
            };
            map.insert(coordinate.to_string(), sigma);
        }
        let mut pred = Predictor::from_scene(&scene).unwrap();
        let nv = pred.model().nv;
        let p0 = DMatrix::identity(2 * nv, 2 * nv) * 1e-6;
        let req = PredictionRequest::new(&scene.q0, &scene.v0)
            .commands(&commands)
            .horizon(1.0)
            .covariance(&p0);
        let traj = pred.predict(&req).unwrap();
        let p = rows_to_matrix(traj.samples.last().unwrap().covariance.as_ref().unwrap());
        (p, traj.saturated_s)
    };
    let (none, saturated_s) = covariance(&[]);
    assert!(saturated_s > 0.0, "never saturated");
    let (all, _) = covariance(&[0, 1, 2, 3, 4, 5]);
    let mut sum = none.clone();
    for (i, term) in terms.iter().enumerate() {
        let (alone, _) = covariance(&[i]);
        println!(
            "{term:?}: {:.2e} of P",
            (&alone - &none).norm() / none.norm()
        );
        assert!((&alone - &none).norm() > 1e-3 * none.norm(), "{term:?}");
        sum += alone - &none;
    }
    let rel = (&all - &sum).norm() / (&all - &none).norm();
    println!("saturated {saturated_s:.3} s; superposition off by {rel:.1e} of the noise's share");
    assert!(rel < 1e-9, "{rel:e}");
}
