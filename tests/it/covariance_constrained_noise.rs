//! Process noise on a coordinate the constraints tie to another, against the reduced system's
//! closed forms: two carriages on parallel rails along x (m₁ = 2 kg, m₂ = 3 kg) coupled
//! q₁ − q₂ = 0 move as one body of M = 5 kg, with a velocity controller on the first
//! (kp 10 N·s/m, no integral).
//! - Inside its effort (±100 N, asked for 0.5 m/s from rest): a white force of density σ_τ on
//!   carriage 1 (`effort_noise`) makes the common velocity an Ornstein–Uhlenbeck process of
//!   rate a = kp/M and density σ_τ/M:
//!   `var v = s² (1 − e^{−2at}) / (2a)`, `cov(q, v) = s² (1 − e^{−at})² / (2a²)`,
//!   `var q = s² (t − 2 (1 − e^{−at})/a + (1 − e^{−2at})/(2a)) / a²` with s = σ_τ/M, the same on
//!   both carriages (and every cross covariance). Acceleration noise σ on carriage 1
//!   (`acceleration_noise`) is the velocity kick m₁σ dt's share: the same with σ_τ = m₁ σ.
//! - Saturated (effort 1 N, asked for 10 m/s): a grip bias σ_b on carriage 1
//!   (`saturation_bias`) is a constant acceleration of m₁σ_b/M on both,
//!   `σ² [t⁴/4, t³/2; t³/2, t²]` with σ = m₁σ_b/M.
//!
//! A term entering at one carriage enters already on the constraint, so these hold at every
//! sample, not only where the running covariance was last projected.

use crate::common::*;
use constraint_dynamics::Scene;
use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{PredictionRequest, Predictor};
use nalgebra::DMatrix;

const URDF: &str = r#"<?xml version="1.0"?>
<robot name="carriages">
  <link name="rail"/>
  <link name="a"><inertial><mass value="2.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="b"><inertial><mass value="3.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="s1" type="prismatic"><parent link="rail"/><child link="a"/>
    <axis xyz="1 0 0"/><limit lower="-100" upper="100" effort="EFFORT" velocity="20"/></joint>
  <joint name="s2" type="prismatic"><parent link="rail"/><child link="b"/>
    <axis xyz="1 0 0"/><limit lower="-100" upper="100" effort="100" velocity="20"/></joint>
</robot>
"#;
const M1: f64 = 2.0;
const M: f64 = 5.0;
const KP: f64 = 10.0;

/// The coupled carriages with carriage 1's effort limit [N] and `uncertainty: {terms}`.
fn carriages(effort: f64, terms: &str) -> Scene {
    let yaml = format!(
        "urdf: carriages.urdf\nbase: fixed\ngravity: [0.0, 0.0, -9.81]\n\
         constraints:\n  - {{ kind: coupling, name: tie, joint_i: s1, joint_j: s2, a: 1.0, b: -1.0, c: 0.0 }}\n\
         actuators:\n  hold: continuous\n  velocity:\n    - {{ joint: s1, kp: {KP}, ki: 0.0 }}\n\
         integration:\n  method: rk4\n  dt: 0.001\n\
         uncertainty: {{ {terms} }}\n"
    );
    let urdf = URDF.replace("EFFORT", &effort.to_string());
    scene_with_urdf("carriages", &urdf, &yaml)
}

/// (t [s], P over [δq₁, δq₂, δv₁, δv₂]) at every sample after the start of a 1 s prediction
/// from rest asked for `target` [m/s] on s1, and the time it spent saturated [s].
fn covariances(scene: &Scene, target: f64) -> (Vec<(f64, DMatrix<f64>)>, f64) {
    let mut pred = Predictor::from_scene(scene)
        .unwrap()
        .with_settings(|s| s.error_estimate = false)
        .unwrap();
    let cmd = Command {
        joint_velocity: [("s1".to_string(), target)].into(),
        ..Default::default()
    };
    let commands = [(0.0, cmd)];
    let p0 = DMatrix::zeros(4, 4);
    let req = PredictionRequest::new(&[0.0, 0.0], &[0.0, 0.0])
        .horizon(1.0)
        .commands(&commands)
        .covariance(&p0);
    let traj = pred.predict(&req).unwrap();
    let samples = (traj.samples.iter())
        .filter(|s| s.t > 0.0)
        .map(|s| (s.t, rows_to_matrix(s.covariance.as_ref().unwrap())))
        .collect();
    (samples, traj.saturated_s)
}

/// The largest relative difference between every entry of each sample's P and the common
/// coordinate's (var q, cov(q, v), var v) at its time.
fn worst_against(samples: &[(f64, DMatrix<f64>)], exact: impl Fn(f64) -> [f64; 3]) -> f64 {
    let mut worst: f64 = 0.0;
    for (t, p) in samples {
        let [qq, qv, vv] = exact(*t);
        for r in 0..4 {
            for c in 0..4 {
                let e = match (r < 2, c < 2) {
                    (true, true) => qq,
                    (false, false) => vv,
                    _ => qv,
                };
                worst = worst.max((p[(r, c)] - e).abs() / e);
            }
        }
    }
    worst
}

#[test]
fn effort_noise_on_a_coupled_carriage_moves_both_as_one_body() {
    const SIGMA_TAU: f64 = 0.8; // N/√Hz
    const SIGMA_ACC: f64 = 0.4; // (m/s²)/√Hz: the same force density on m₁ = 2 kg
    let a = KP / M;
    let s2 = (SIGMA_TAU / M).powi(2);
    let ou = |t: f64| {
        let (e1, e2) = ((-a * t).exp(), (-2.0 * a * t).exp());
        [
            s2 * (t - 2.0 * (1.0 - e1) / a + (1.0 - e2) / (2.0 * a)) / (a * a),
            s2 * (1.0 - e1).powi(2) / (2.0 * a * a),
            s2 * (1.0 - e2) / (2.0 * a),
        ]
    };
    for (what, terms) in [
        (
            "effort_noise",
            format!("effort_noise: {{ s1: {SIGMA_TAU} }}"),
        ),
        (
            "acceleration_noise",
            format!("acceleration_noise: {{ s1: {SIGMA_ACC} }}"),
        ),
    ] {
        let (samples, saturated_s) = covariances(&carriages(100.0, &terms), 0.5);
        assert_eq!(saturated_s, 0.0, "{what}");
        // Over chunks of H the velocity block is Q (1 − A^{2k}) / (1 − A²) with A = e^{−aH},
        // δ = A − 1 and Q = s² H ((1 + δ/2)² + δ²/12) (covariance_noise.rs): this tells the
        // share that enters, 1/M of the force, to rounding.
        let h = samples[0].0;
        let damping = (-a * h).exp();
        let delta = damping - 1.0;
        let q = s2 * h * ((1.0 + delta / 2.0).powi(2) + delta * delta / 12.0);
        let mut chunked: f64 = 0.0;
        for (t, p) in &samples {
            let k = (t / h).round() as i32;
            let vv = q * (1.0 - damping.powi(2 * k)) / (1.0 - damping * damping);
            for (r, c) in [(2, 2), (2, 3), (3, 3)] {
                chunked = chunked.max((p[(r, c)] - vv).abs() / vv);
            }
        }
        // Every entry against the continuous forms: the transition taken linear in time over a
        // chunk is off by O(aH) in the positions' share of the chunk's own noise, which the
        // earlier chunks' outweigh from 0.1 s on.
        let later: Vec<_> = samples
            .iter()
            .filter(|s| s.0 >= 0.1 - 1e-9)
            .cloned()
            .collect();
        let continuous = worst_against(&later, ou);
        println!(
            "{what}: velocity block against the chunked form {chunked:.2e}, every entry \
             against the Ornstein–Uhlenbeck forms from 0.1 s {continuous:.2e}"
        );
        assert!(chunked < 5e-9, "{what}: {chunked:e}");
        assert!(continuous < 1e-3, "{what}: {continuous:e}");
    }
}

#[test]
fn a_grip_bias_on_a_coupled_carriage_is_its_share_of_the_body() {
    const SIGMA_BIAS: f64 = 0.5; // m/s²
    let (samples, saturated_s) = covariances(
        &carriages(1.0, &format!("saturation_bias: {{ s1: {SIGMA_BIAS} }}")),
        10.0,
    );
    assert!((saturated_s - 1.0).abs() < 1e-12, "{saturated_s}");
    let b2 = (M1 * SIGMA_BIAS / M).powi(2);
    let worst = worst_against(&samples, |t| {
        [b2 * t.powi(4) / 4.0, b2 * t.powi(3) / 2.0, b2 * t * t]
    });
    println!("saturation_bias: worst relative difference {worst:.2e}");
    assert!(worst < 1e-9, "{worst:e}");
}
