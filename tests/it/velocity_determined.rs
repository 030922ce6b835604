//! `virtual_displacements: velocity_determined` (seed 001, eqs. 5–6, 10) against closed forms,
//! on a constraint that is not homogeneous in the velocities, where it differs from Chetaev's:
//! a point mass under gravity with ż = a (ẋ² + ẏ²), dependent ż, in the embedded form.
//!
//! With q̂ = a (u_x² + u_y²), eq. (6) about v⁽⁰⁾ gives B_α = ∫₀¹ 2a (v⁰_α + σ (v_α − v⁰_α)) dσ
//! = a (v_α + v⁰_α) (Chetaev's is 2a v_α). Eq. (10): m ẍ_α + P B_α = 0 with P = m (z̈ + g), and
//! z̈ = 2a (ẋ ẍ + ẏ ÿ) (f differentiated), so with K = Σ v_α (v_α + v⁰_α):
//!   P = m g/(1 + 2a² K),  ẍ_α = −(P/m) a (v_α + v⁰_α),  z̈ = −2a² K P/m.
//! Chetaev (B = 2a v_α): P = m g/(1 + 4a² s²), ẍ_α = −2a v_α P/m, z̈ = −4a² s² P/m.
//! With v⁰ = 0, B v_i = q̂(v_i) = ż: the velocity itself is a virtual displacement, the force
//! does no work and the energy is conserved (Chetaev's force does work here); the speed obeys
//! ṡ = −g a s/(1 + 2a² s²), i.e. ln s + a² s² = ln s₀ + a² s₀² − g a t.

use crate::common;
use common::*;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::predict::{DriftControl, Method, PredictionRequest, Predictor};
use constraint_dynamics::{Error, Scene, System};

const A: f64 = 0.2;
const G: f64 = 9.81;

fn scene(vd: bool, reference: &str) -> Scene {
    let urdf = repo_dir().join("urdf/point_mass.urdf");
    let extra = if vd {
        format!("    virtual_displacements: velocity_determined\n{reference}")
    } else {
        String::new()
    };
    let yaml = format!(
        "urdf: {:?}\nbase: floating\ndynamics: {{formulation: embedded}}\nconstraints:\n  - name: lift\n    kind: velocity\n    expression: \"vz - {A}*(vx^2 + vy^2)\"\n    variables: {{vx: \"v:root_joint:vx_local\", vy: \"v:root_joint:vy_local\", vz: \"v:root_joint:vz_local\"}}\n    dependent: [vz]\n{extra}",
        urdf.display().to_string()
    );
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let path = std::env::temp_dir().join(format!(
        "velocity_determined_{}_{}.yaml",
        std::process::id(),
        N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    std::fs::write(&path, yaml).unwrap();
    let sc = Scene::load(&path);
    let _ = std::fs::remove_file(&path);
    sc.unwrap()
}

fn state(vx: f64, vy: f64) -> (Vec<f64>, Vec<f64>) {
    (
        vec![0.3, -0.2, 1.0, 0.0, 0.0, 0.0, 1.0],
        vec![vx, vy, A * (vx * vx + vy * vy), 0.0, 0.0, 0.0],
    )
}

#[test]
fn velocity_determined_accelerations_match_the_closed_form_and_differ_from_chetaev() {
    let mut vd = System::from_scene(&scene(true, "")).unwrap();
    let mut ch = System::from_scene(&scene(false, "")).unwrap();
    let v0 = [0.7, -0.4];
    let mut vd_ref = System::from_scene(&scene(
        true,
        &format!("    reference_velocity: {{vx: {}, vy: {}}}\n", v0[0], v0[1]),
    ))
    .unwrap();
    let tau = [0.0; 6];
    for (vx, vy) in [(3.0, 4.0), (-1.5, 0.5), (0.2, -2.5)] {
        let (q, v) = state(vx, vy);
        let s2 = vx * vx + vy * vy;
        let p = G / (1.0 + 2.0 * A * A * s2);
        let expect = [
            -p * A * vx,
            -p * A * vy,
            -2.0 * A * A * s2 * p,
            0.0,
            0.0,
            0.0,
        ];
        let got = vd.forward_dynamics(&q, &v, &tau, false).unwrap().clone();
        // Achieved ≤ 6.2e-16 for the three (8-point Gauss–Legendre is exact for this quadratic
        // q̂).
        assert_close(
            &format!("VD q̈ at ({vx}, {vy})"),
            got.as_slice(),
            &expect,
            1e-14,
        );
        let pc = G / (1.0 + 4.0 * A * A * s2);
        let expect_ch = [
            -2.0 * A * vx * pc,
            -2.0 * A * vy * pc,
            -4.0 * A * A * s2 * pc,
            0.0,
            0.0,
            0.0,
        ];
        let got_ch = ch.forward_dynamics(&q, &v, &tau, false).unwrap().clone();
        assert_close(
            &format!("Chetaev q̈ at ({vx}, {vy})"),
            got_ch.as_slice(),
            &expect_ch,
            1e-14,
        );
        assert!(
            rel_err(got.as_slice(), got_ch.as_slice()) > 1e-2,
            "VD = Chetaev?"
        );
        // With a reference velocity v⁰: B_α = a (v_α + v⁰_α).
        let k = vx * (vx + v0[0]) + vy * (vy + v0[1]);
        let pr = G / (1.0 + 2.0 * A * A * k);
        let expect_r = [
            -pr * A * (vx + v0[0]),
            -pr * A * (vy + v0[1]),
            -2.0 * A * A * k * pr,
            0.0,
            0.0,
            0.0,
        ];
        let got_r = vd_ref
            .forward_dynamics(&q, &v, &tau, false)
            .unwrap()
            .clone();
        assert_close(
            &format!("VD q̈ about v⁰ at ({vx}, {vy})"),
            got_r.as_slice(),
            &expect_r,
            1e-14,
        );
    }
    // The multiplier form refuses it by name (its force is not along ∂f/∂v).
    let (q, v) = state(3.0, 4.0);
    let opts = constraint_dynamics::system::DynamicsOptions {
        formulation: Formulation::Multipliers,
        ..Default::default()
    };
    match vd.forward_dynamics_with(&q, &v, &tau, opts) {
        Err(Error::Unsupported { what, .. }) => assert!(what.contains("'lift'"), "{what}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn velocity_determined_motion_conserves_energy_where_chetaev_does_not() {
    let run = |vd: bool| {
        let sc = scene(vd, "");
        let sys = System::from_scene(&sc).unwrap();
        assert_eq!(sys.formulation(), Formulation::Embedded);
        let mut p = Predictor::from_scene(&sc)
            .unwrap()
            .with_settings(|s| {
                s.method = Method::Rk4;
                s.dt = 1e-3;
                s.drift = DriftControl::Projection;
                s.sample_period = 0.1;
                // Chetaev's force does so much work here that the passive-scene energy guard
                // would stop the run; the comparison wants to see it.
                s.max_energy_error = 1e3;
            })
            .unwrap();
        let (q, v) = state(3.0, 4.0);
        p.predict(&PredictionRequest::new(&q, &v).horizon(1.0))
            .unwrap()
    };
    let energy = |s: &constraint_dynamics::predict::Sample| s.kinetic_energy + s.potential_energy;
    let t_vd = run(true);
    let e0 = energy(&t_vd.samples[0]);
    let s0: f64 = 5.0;
    let (mut we, mut ws) = (0.0f64, 0.0f64);
    for smp in &t_vd.samples {
        we = we.max((energy(smp) - e0).abs() / e0);
        // s(t) from ln s + a² s² = ln s₀ + a² s₀² − g a t, by Newton.
        let c = s0.ln() + A * A * s0 * s0 - G * A * smp.t;
        let mut s = s0;
        for _ in 0..50 {
            s -= (s.ln() + A * A * s * s - c) / (1.0 / s + 2.0 * A * A * s);
        }
        let speed = (smp.v[0] * smp.v[0] + smp.v[1] * smp.v[1]).sqrt();
        ws = ws.max((speed - s).abs() / s0);
    }
    // RK4, dt = 1 ms: achieved energy 1.2e-15, speed 6.4e-15 (relative).
    assert_close("VD energy over 1 s", &[we], &[0.0], 1e-12);
    assert_close("VD speed s(t) (implicit closed form)", &[ws], &[0.0], 1e-12);
    let t_ch = run(false);
    let e0 = energy(&t_ch.samples[0]);
    let drift = (energy(t_ch.samples.last().unwrap()) - e0).abs() / e0;
    eprintln!("Chetaev energy change over 1 s: {drift:.3e} (the force does work)");
    assert!(drift > 1e-3);
}

#[test]
fn velocity_determined_needs_a_dependent_velocity() {
    let urdf = repo_dir().join("urdf/point_mass.urdf");
    let yaml = format!(
        "urdf: {:?}\nbase: floating\nconstraints:\n  - name: lift\n    kind: velocity\n    expression: \"vz - vx^2\"\n    variables: {{vx: \"v:root_joint:vx_local\", vz: \"v:root_joint:vz_local\"}}\n    virtual_displacements: velocity_determined\n",
        urdf.display().to_string()
    );
    let path = std::env::temp_dir().join(format!("vd_no_dep_{}.yaml", std::process::id()));
    std::fs::write(&path, yaml).unwrap();
    let sc = Scene::load(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    match System::from_scene(&sc) {
        Err(Error::Expression { problem, .. }) => {
            assert!(problem.to_string().contains("needs dependent"), "{problem}")
        }
        other => panic!("{:?}", other.err()),
    }
}

/// B for a constraint nonlinear in its dependent velocity, f = ż³ + ż − ẋ on the point mass
/// (`dependent: [vz]`, reference ẋ⁰ = 1): with one independent velocity, eq. (6) integrates to
/// B = (q̂(ẋ) − q̂(ẋ⁰)) / (ẋ − ẋ⁰) (fundamental theorem of calculus); at ẋ = 2, q̂ = 1, and
/// q̂(1) is the real root of z³ + z = 1 (Cardano). B is evaluated where Newton has solved f = 0
/// at each quadrature node, so this needs Newton to run (the tests above use an f linear in ż,
/// whose B does not). ẋ⁰ = 1 keeps the interval [1, 2] away from q̂'s branch points at
/// ẋ = ±0.385i, where 8-point Gauss–Legendre converges slowly (from ẋ⁰ = 0 it reaches 5e-6).
#[test]
fn b_of_a_constraint_nonlinear_in_the_dependent_velocity() {
    use constraint_dynamics::constraints::{VelocityConstraint, VirtualDisplacements};
    use constraint_dynamics::{BaseType, Model, ModelOptions};
    use std::collections::BTreeMap;
    let model = Model::from_urdf_file(
        repo_dir().join("urdf/point_mass.urdf"),
        &ModelOptions {
            base: BaseType::Floating,
            ..Default::default()
        },
    )
    .unwrap();
    let vars: BTreeMap<String, String> = [
        ("vx".to_string(), "v:root_joint:vx_local".to_string()),
        ("vz".to_string(), "v:root_joint:vz_local".to_string()),
    ]
    .into();
    let c = VelocityConstraint::build(
        &model,
        "c",
        "vz^3 + vz - vx",
        &vars,
        VirtualDisplacements::VelocityDetermined,
        &["vz".to_string()],
        &BTreeMap::from([("vx".to_string(), 1.0)]),
    )
    .unwrap();
    let q = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    // v_z given away from the solution (Newton starts there).
    let b = c
        .velocity_determined_b(&q, &[2.0, 0.0, 0.3, 0.0, 0.0, 0.0], 0.0)
        .unwrap();
    assert_eq!(b.len(), 1);
    assert_eq!(b[0].0, 0);
    let d = (0.25f64 + 1.0 / 27.0).sqrt();
    let root1 = (0.5 + d).cbrt() + (0.5 - d).cbrt(); // z³ + z = 1 by Cardano
    assert_close("B", &[b[0].1], &[1.0 - root1], 1e-12); // achieved 3.7e-14 (closed form (q̂(2) − q̂(1)) / (2 − 1))
}

/// Newton's stopping test in `velocity_determined_b` is relative to the size of the dependent
/// velocity: at |v_d| ≈ 1000 the residual of f = v_z − v_x − 0.1 cannot fall below 2⁻⁵⁶ ≈
/// 1.4e-17 (v_z − v_x is a multiple of ulp(1000) = 2⁻⁴³, 0.1 is not), well inside 1e-14 |v_d|.
/// q̂(v_x) = v_x + 0.1, so B = (q̂(1000) − q̂(0)) / 1000 = 1 (reference v_x⁰ = 0).
#[test]
fn b_at_a_large_dependent_velocity() {
    use constraint_dynamics::constraints::{VelocityConstraint, VirtualDisplacements};
    use constraint_dynamics::{BaseType, Model, ModelOptions};
    use std::collections::BTreeMap;
    let model = Model::from_urdf_file(
        repo_dir().join("urdf/point_mass.urdf"),
        &ModelOptions {
            base: BaseType::Floating,
            ..Default::default()
        },
    )
    .unwrap();
    let vars: BTreeMap<String, String> = [
        ("vx".to_string(), "v:root_joint:vx_local".to_string()),
        ("vz".to_string(), "v:root_joint:vz_local".to_string()),
    ]
    .into();
    let c = VelocityConstraint::build(
        &model,
        "c",
        "vz - vx - 0.1",
        &vars,
        VirtualDisplacements::VelocityDetermined,
        &["vz".to_string()],
        &BTreeMap::new(),
    )
    .unwrap();
    let q = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let b = c
        .velocity_determined_b(&q, &[1000.0, 0.0, 3.0, 0.0, 0.0, 0.0], 0.0)
        .unwrap();
    assert_eq!(b.len(), 1);
    assert_eq!(b[0].0, 0);
    assert_close("B", &[b[0].1], &[1.0], 1e-15); // achieved 0 (linear q̂; floor 1e-15)
}

/// Where Newton cannot take a step (∂f/∂v_d = 0 at its start, f = v_z² − v_x from v_z = 0) or f
/// is not defined (f = v_z − ln(v_x − 0.5), undefined for v_x ≤ 0.5, on the way from v_x⁰ = 0),
/// `velocity_determined_b` says so at the first node it visits (σ = (1 − 0.1834)/2 = 0.408,
/// of the innermost Gauss–Legendre pair), instead of iterating on ∞ or NaN.
#[test]
fn b_where_newton_cannot_start_names_the_cause() {
    use constraint_dynamics::constraints::{VelocityConstraint, VirtualDisplacements};
    use constraint_dynamics::{BaseType, Model, ModelOptions};
    use std::collections::BTreeMap;
    let model = Model::from_urdf_file(
        repo_dir().join("urdf/point_mass.urdf"),
        &ModelOptions {
            base: BaseType::Floating,
            ..Default::default()
        },
    )
    .unwrap();
    let vars: BTreeMap<String, String> = [
        ("vx".to_string(), "v:root_joint:vx_local".to_string()),
        ("vz".to_string(), "v:root_joint:vz_local".to_string()),
    ]
    .into();
    let q = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    for f in ["vz^2 - vx", "vz - ln(vx - 0.5)"] {
        let c = VelocityConstraint::build(
            &model,
            "c",
            f,
            &vars,
            VirtualDisplacements::VelocityDetermined,
            &["vz".to_string()],
            &BTreeMap::new(),
        )
        .unwrap();
        let e = c
            .velocity_determined_b(&q, &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0.0)
            .unwrap_err();
        assert_eq!(e, "f or ∂f/∂v_d undefined at σ = 0.408", "{f}");
    }
}
