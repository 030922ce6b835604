//! The constant form of a scene's constrained dynamics (`predict::InvariantDynamics`): built
//! where q̈ depends on no coordinate, held to the differential drive's closed forms, and refused
//! where a coordinate matters.
//!
//! The diff drive (urdf/diff_drive.urdf) in its forward speed v and yaw rate ω at the axle
//! midpoint A, wheel rates (v ∓ (b/2) ω)/r (left, right), its centre of mass a distance d ahead
//! of A (d < 0: behind):
//! `(m + 2 I_s/r²) v̇ − m d ω² = (τ_R + τ_L)/r` and
//! `(I_A + 2 I_s (b/2)²/r²) ω̇ + m d ω v = (b/2)(τ_R − τ_L)/r`,
//! with m the total mass, I_s a wheel's spin inertia and I_A the yaw inertia about A (Newton on
//! the body: the axle's lateral force m (v ω + d ω̇) turns the base about its centre of mass).

use constraint_dynamics::Scene;
use constraint_dynamics::predict::InvariantDynamics;
use constraint_dynamics::system::System;
use std::path::PathBuf;

fn scene(name: &str) -> Scene {
    Scene::load(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("params")
            .join(name),
    )
    .unwrap()
}

/// The diff drive's constants from urdf/diff_drive.urdf: chassis 8 kg at (−0.05, 0), izz 1/6;
/// caster 0.2 kg at (−0.15, 0), I 5e-5; wheels 0.5 kg at (0, ±0.17), spin 6.25e-4, izz 3.5e-4;
/// r = 0.05 m.
struct DiffDrive {
    m: f64,
    md: f64,
    i_a: f64,
    spin: f64,
    r: f64,
    half_track: f64,
}

const DD: DiffDrive = DiffDrive {
    m: 8.0 + 0.2 + 2.0 * 0.5,
    md: 8.0 * -0.05 + 0.2 * -0.15,
    i_a: (1.0 / 6.0 + 8.0 * 0.05 * 0.05)
        + (5e-5 + 0.2 * 0.15 * 0.15)
        + 2.0 * (3.5e-4 + 0.5 * 0.17 * 0.17),
    spin: 6.25e-4,
    r: 0.05,
    half_track: 0.17,
};

impl DiffDrive {
    /// The mass and the yaw inertia about A that the closed forms divide by, the wheels' spin
    /// included: (m + 2 I_s/r², I_A + 2 I_s (b/2)²/r²).
    fn inertias(&self) -> (f64, f64) {
        let (r, h) = (self.r, self.half_track);
        (
            self.m + 2.0 * self.spin / (r * r),
            self.i_a + 2.0 * self.spin * h * h / (r * r),
        )
    }
}

/// (v̇, ω̇) of the closed forms above.
fn closed_form(v: f64, w: f64, tau_l: f64, tau_r: f64) -> (f64, f64) {
    let (mass, yaw_inertia) = DD.inertias();
    let (md, r, h) = (DD.md, DD.r, DD.half_track);
    let vdot = ((tau_r + tau_l) / r + md * w * w) / mass;
    let wdot = (h * (tau_r - tau_l) / r - md * w * v) / yaw_inertia;
    (vdot, wdot)
}

#[test]
fn the_diff_drive_has_a_form_that_meets_its_closed_forms() {
    let scene = scene("diff_drive.yaml");
    let mut sys = System::from_scene(&scene).unwrap();
    let form = InvariantDynamics::fit(&mut sys, &scene.q0).expect("the diff drive has a form");
    // v: root_joint (vx_local, vy_local, ω), left wheel, right wheel.
    let (r, h) = (DD.r, DD.half_track);
    let mut worst = 0.0f64;
    for &(v, w, tau_l, tau_r) in &[
        (0.0, 0.0, 1.0, 1.0),
        (0.0, 0.0, -1.0, 1.0),
        (0.0, 2.0, 0.0, 0.0),
        (0.4, -1.5, 0.3, -0.7),
        (-0.8, 3.0, 2.0, 5.0),
    ] {
        let vel = [v, 0.0, w, (v - h * w) / r, (v + h * w) / r];
        let mut tau = [0.0; 5];
        (tau[3], tau[4]) = (tau_l, tau_r);
        let mut qdd = [0.0; 5];
        form.accel(&vel, &tau, &mut qdd);
        let (vdot, wdot) = closed_form(v, w, tau_l, tau_r);
        // q̈ holds the rates of the body-axes components (v̇, 0, ω̇): the axle does not slip
        // sideways, so the lateral component stays zero.
        let expected = [
            vdot,
            0.0,
            wdot,
            (vdot - h * wdot) / r,
            (vdot + h * wdot) / r,
        ];
        for (a, b) in qdd.iter().zip(&expected) {
            worst = worst.max((a - b).abs() / b.abs().max(1.0));
        }
    }
    println!("diff drive form against its closed forms: worst relative {worst:.2e}");
    assert!(worst < 1e-13, "{worst:e}");
    // On the constraints: the wheels roll at (v ∓ h ω)/r with no sideways speed. A sideways
    // speed or a wheel off its rolling rate by 1e-6 leaves them.
    let rolling = [0.4, 0.0, -1.5, (0.4 + h * 1.5) / r, (0.4 - h * 1.5) / r];
    assert!(form.on_constraints(&rolling, 1e-9));
    for (i, dv) in [(1, 1e-6), (3, 1e-6), (4, -1e-6)] {
        let mut off = rolling;
        off[i] += dv;
        assert!(!form.on_constraints(&off, 1e-9), "v[{i}] + {dv:e}");
    }
}

#[test]
fn the_forms_derivatives_are_those_of_the_closed_forms() {
    let scene = scene("diff_drive.yaml");
    let mut sys = System::from_scene(&scene).unwrap();
    let form = InvariantDynamics::fit(&mut sys, &scene.q0).expect("the diff drive has a form");
    let (mass, yaw_inertia) = DD.inertias();
    let (md, r, h) = (DD.md, DD.r, DD.half_track);
    let rolling = |v: f64, w: f64| [v, 0.0, w, (v - h * w) / r, (v + h * w) / r];
    let z = || nalgebra::DMatrix::<f64>::from_element(5, 5, f64::NAN);
    let (mut dq, mut dv, mut dtau) = (z(), z(), z());
    let mut worst = 0.0f64;
    for &(v, w) in &[(0.0, 0.0), (0.4, -1.5), (-0.8, 3.0)] {
        form.derivatives(&rolling(v, w), &mut dq, &mut dv, &mut dtau);
        assert!(dq.iter().all(|&x| x == 0.0), "no coordinate enters q̈");
        // Differentiating the closed forms: a velocity change (δv, δω) on the constraints moves
        // v̇ by 2 m d ω δω / M and ω̇ by −m d (ω δv + v δω) / I; a torque change by (δτ_R ± δτ_L).
        let (d_v, d_w) = (0.3, 0.7);
        let (vdot, wdot) = (
            2.0 * md * w * d_w / mass,
            -md * (w * d_v + v * d_w) / yaw_inertia,
        );
        let along = &dv * nalgebra::DVector::from_row_slice(&rolling(d_v, d_w));
        let (d_l, d_r) = (0.2, -0.9);
        let (tdot_v, tdot_w) = ((d_r + d_l) / r / mass, h * (d_r - d_l) / r / yaw_inertia);
        let by_tau = &dtau * nalgebra::DVector::from_row_slice(&[0.0, 0.0, 0.0, d_l, d_r]);
        for (got, (a, b)) in [(along, (vdot, wdot)), (by_tau, (tdot_v, tdot_w))] {
            let expected = rolling(a, b);
            for (g, e) in got.iter().zip(&expected) {
                worst = worst.max((g - e).abs() / e.abs().max(1.0));
            }
        }
    }
    println!("the form's derivatives against the closed forms': worst relative {worst:.2e}");
    assert!(worst < 1e-13, "{worst:e}");
}

#[test]
fn a_coordinate_that_matters_refuses_the_form() {
    // The arm's configuration changes M; the four-bar's loop closure has position rows.
    for name in ["suite_mobile_manipulator.yaml", "fourbar.yaml"] {
        let scene = scene(name);
        let mut sys = System::from_scene(&scene).unwrap();
        assert!(
            InvariantDynamics::fit(&mut sys, &scene.q0).is_none(),
            "{name} has no constant form"
        );
    }
}
