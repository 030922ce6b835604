//! `kind: velocity` — f(q, v, t) = 0 written as an expression, against independent
//! sources: Appell–Hamel's closed form, the built-in rolling constraint (the seed's disk written
//! as its eqs. (31), (32)), finite differences of the expression, and the error messages.
//! Tolerances: the achieved figure (printed by `assert_close`, `-- --nocapture`) with a margin.

use crate::common;
use common::*;
use constraint_dynamics::constraints::ConstraintKind;
use constraint_dynamics::dynamics::{Baumgarte, Formulation};
use constraint_dynamics::predict::{DriftControl, Method, PredictionRequest, Predictor};
use constraint_dynamics::{Scene, System};

use crate::counting_alloc;
use counting_alloc::allocations;

fn load(rel: &str) -> Scene {
    Scene::load(repo_dir().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

// ---------------------------------------------------------------------------------------------
// Appell–Hamel: ż = a √(ẋ² + ẏ²), a point mass under gravity.
// ---------------------------------------------------------------------------------------------

/// f = ż − a s, s = √(ẋ² + ẏ²); Chetaev's force λ ∂f/∂v = λ (−a ẋ/s, −a ẏ/s, 1):
///   m ẍ = −λ a ẋ/s,  m ÿ = −λ a ẏ/s,  m z̈ = −m g + λ.
/// The horizontal direction stays fixed and ṡ = −λ a/m; with z̈ = a ṡ (the constraint
/// differentiated), λ = m (g + a ṡ), so ṡ = −g a/(1 + a²), λ = m g/(1 + a²), and
///   s(t) = s₀ − g a t/(1 + a²),  d(t) = s₀ t − g a t²/(2(1 + a²)),  (x, y) = d e,  z = z₀ + a d.
/// ∂f/∂v · v = f (homogeneous of degree 1), so the force does no work: E = ½ m (s² + ż²) + m g z
/// is constant.
#[test]
fn appell_hamel_follows_its_closed_form() {
    let (a, g, m, s0, z0) = (0.5, 9.81, 1.0, 10.0, 1.0);
    let e = [0.8, 0.6];
    let sc = load("params/appell_hamel.yaml");
    let sys = System::from_scene(&sc).unwrap();
    assert_eq!(sys.constraints().items[0].kind(), ConstraintKind::Velocity);
    let mut p = Predictor::from_scene(&sc)
        .unwrap()
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.dt = 1e-3;
            s.drift = DriftControl::Projection;
            s.sample_period = 0.1;
        })
        .unwrap();
    let req = PredictionRequest::new(&sc.q0, &sc.v0)
        .horizon(2.0)
        .forces(true);
    let traj = p.predict(&req).unwrap();
    assert!(traj.samples.len() >= 21);
    assert!((traj.samples.last().unwrap().t - 2.0).abs() < 1e-9);
    let sd = -g * a / (1.0 + a * a);
    let lam = m * g / (1.0 + a * a);
    let e0 = 0.5 * m * (s0 * s0 + (a * s0) * (a * s0)) + m * g * z0;
    let (mut wq, mut wv, mut wl, mut we) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for smp in &traj.samples {
        let t = smp.t;
        let s = s0 + sd * t;
        let d = s0 * t + 0.5 * sd * t * t;
        let q_cf = [e[0] * d, e[1] * d, z0 + a * d, 0.0, 0.0, 0.0, 1.0];
        let v_cf = [e[0] * s, e[1] * s, a * s, 0.0, 0.0, 0.0];
        wq = wq.max(rel_err(&smp.q, &q_cf));
        wv = wv.max(rel_err(&smp.v, &v_cf));
        wl = wl.max(rel_err(smp.lambda.as_ref().unwrap(), &[lam]));
        we = we.max(((smp.kinetic_energy + smp.potential_energy) - e0).abs() / e0);
    }
    // RK4 integrates this motion exactly (constant accelerations), so what is left is
    // round-off grown over 2000 steps and their velocity projections: achieved q 5.3e-14,
    // v 2.0e-13, λ 1.1e-16, energy 6.1e-14 relative (the required bar is 1e-9).
    assert_close("Appell–Hamel q (x, y, z, quaternion)", &[wq], &[0.0], 5e-12);
    assert_close("Appell–Hamel v (ẋ, ẏ, ż)", &[wv], &[0.0], 2e-11);
    assert_close("Appell–Hamel λ = m g/(1 + a²)", &[wl], &[0.0], 1e-14);
    assert_close("Appell–Hamel energy", &[we], &[0.0], 5e-12);
}

/// Energy to the method's order where the motion is not polynomial: semi-implicit Euler
/// (order 1) leaves an energy error that halves with dt, Baumgarte drift control off.
#[test]
fn appell_hamel_energy_error_has_the_methods_order() {
    let sc = load("params/appell_hamel.yaml");
    let run = |dt: f64| {
        let mut p = Predictor::from_scene(&sc)
            .unwrap()
            .with_settings(|s| {
                s.method = Method::SemiImplicitEuler;
                s.dt = dt;
                s.drift = DriftControl::None;
                s.sample_period = 0.5;
                // The order is measured at coarse steps whose error exceeds the default
                // max_error.
                s.max_error = f64::INFINITY;
            })
            .unwrap();
        let traj = p
            .predict(&PredictionRequest::new(&sc.q0, &sc.v0).horizon(1.0))
            .unwrap();
        let e = |s: &constraint_dynamics::predict::Sample| s.kinetic_energy + s.potential_energy;
        let e0 = e(&traj.samples[0]);
        (e(traj.samples.last().unwrap()) - e0).abs() / e0
    };
    let (e1, e2) = (run(2e-3), run(1e-3));
    let order = (e1 / e2).log2();
    eprintln!("semi-implicit Euler energy error {e1:.3e} → {e2:.3e}: order {order:.3}");
    // Achieved 1.000 (2.66e-4 → 1.33e-4).
    assert!((order - 1.0).abs() < 0.05, "observed order {order}");
}

// ---------------------------------------------------------------------------------------------
// Seed 001 §3: the rolling disk as expressions = the built-in rolling constraint.
// ---------------------------------------------------------------------------------------------

/// States on the constraint (vx_local = a·spin_rate, vy_local = 0) with torques on every
/// coordinate, so that q̈ is not zero.
fn disk_states() -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let a = 0.1;
    let st = |x: f64, y: f64, yaw: f64, ang: f64, spin: f64, wz: f64, k: f64| {
        (
            vec![x, y, yaw, ang],
            vec![a * spin, 0.0, wz, spin],
            vec![0.3 * k, -0.2 * k, 0.05 * k, 0.02 * k],
        )
    };
    vec![
        st(0.0, 0.0, 0.0, 0.0, 10.0, 0.5, 0.0),
        st(0.3, -0.7, 1.2, 0.4, -6.0, 1.3, 1.0),
        st(-1.0, 2.0, -2.5, 3.0, 4.0, -0.8, -2.0),
        st(2.0, 0.5, 3.0, -1.0, 0.0, 0.0, 1.5),
    ]
}

#[test]
fn seed_disk_as_expressions_gives_the_rolling_constraints_accelerations() {
    let mut builtin = System::from_scene(&load("params/vertical_disk.yaml")).unwrap();
    let mut expr = System::from_scene(&load("params/vertical_disk_expressions.yaml")).unwrap();
    assert_eq!(expr.constraints().nrows, 2);
    for (k, (q, v, tau)) in disk_states().iter().enumerate() {
        let a_ref = builtin.forward_dynamics(q, v, tau, true).unwrap().clone();
        let f_ref = builtin.multipliers().generalized_force.clone();
        let a_mul = expr.forward_dynamics(q, v, tau, true).unwrap().clone();
        assert_close(
            &format!("state {k}: f"),
            expr.rows().jv.as_slice(),
            &[0.0; 2],
            1e-15,
        );
        // Achieved ≤ 2.2e-16 (q̈, both forms) and 2.2e-16 (Jᵀλ): the same force through other
        // rows (the required bar is 1e-12).
        assert_close(
            &format!("state {k}: q̈ multipliers"),
            a_mul.as_slice(),
            a_ref.as_slice(),
            2e-14,
        );
        assert_close(
            &format!("state {k}: Jᵀλ"),
            expr.multipliers().generalized_force.as_slice(),
            f_ref.as_slice(),
            2e-14,
        );
        let a_emb = expr.forward_dynamics(q, v, tau, false).unwrap().clone();
        assert_eq!(expr.last_formulation(), Formulation::Embedded);
        assert_close(
            &format!("state {k}: q̈ embedded"),
            a_emb.as_slice(),
            a_ref.as_slice(),
            2e-14,
        );
    }
}

#[test]
fn seed_disk_as_expressions_moves_like_the_rolling_constraint() {
    let run = |rel: &str, f: Formulation| {
        let mut sc = load(rel);
        sc.file.dynamics.formulation = f;
        let mut p = Predictor::from_scene(&sc)
            .unwrap()
            .with_settings(|s| {
                s.method = Method::Rk4;
                s.dt = 1e-3;
                s.drift = DriftControl::Projection;
                s.sample_period = 0.1;
            })
            .unwrap();
        p.predict(&PredictionRequest::new(&sc.q0, &sc.v0).horizon(2.0))
            .unwrap()
    };
    let reference = run("params/vertical_disk.yaml", Formulation::Multipliers);
    for f in [Formulation::Multipliers, Formulation::Embedded] {
        let t = run("params/vertical_disk_expressions.yaml", f);
        assert_eq!(t.samples.len(), reference.samples.len());
        let (mut wq, mut wv) = (0.0f64, 0.0f64);
        for (a, b) in t.samples.iter().zip(&reference.samples) {
            wq = wq.max(rel_err(&a.q, &b.q));
            wv = wv.max(rel_err(&a.v, &b.v));
        }
        // Achieved 5.6e-17 (q), 5.3e-16 (v) over 2 s with both forms (bar 1e-12).
        assert_close(&format!("{f:?}: motion q over 2 s"), &[wq], &[0.0], 5e-14);
        assert_close(&format!("{f:?}: motion v over 2 s"), &[wv], &[0.0], 5e-14);
    }
}

// ---------------------------------------------------------------------------------------------
// Expression derivatives against finite differences.
// ---------------------------------------------------------------------------------------------

/// J = ∂f/∂v by central differences in v; γ = d/dt f along (q ⊕ h v, v, t + h), i.e.
/// ∂f/∂q G(q) v + ∂f/∂t, by central differences in h on the configuration's Lie group.
/// Richardson-extrapolated (h = 1e-3, h/2): worst achieved 2.6e-13 (the differences' own
/// error), tolerance 1e-11.
fn check_rows_against_differences(sys: &mut System, q: &[f64], v: &[f64], t: f64) -> f64 {
    let (nv, nc) = (sys.model().nv, sys.constraints().nrows);
    sys.evaluate_rows(t, q, v);
    let (j, gamma) = (sys.rows().j.clone(), sys.rows().gamma.clone());
    let model = sys.model().clone();
    let mut f_at = |q: &[f64], v: &[f64], t: f64| -> Vec<f64> {
        sys.evaluate_rows(t, q, v);
        sys.rows().jv.as_slice().to_vec()
    };
    let central = |g: &mut dyn FnMut(f64) -> Vec<f64>, h: f64| -> Vec<f64> {
        let mut d = |h: f64| {
            let (p, m) = (g(h), g(-h));
            p.iter()
                .zip(&m)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect::<Vec<_>>()
        };
        let (d1, d2) = (d(h), d(h / 2.0));
        d1.iter()
            .zip(&d2)
            .map(|(a, b)| (4.0 * b - a) / 3.0)
            .collect()
    };
    // γ along the flow.
    let mut qh = vec![0.0; q.len()];
    let gamma_fd = central(
        &mut |h| {
            model.integrate(q, v, h, &mut qh);
            f_at(&qh, v, t + h)
        },
        1e-3,
    );
    let mut worst = rel_err(gamma.as_slice(), &gamma_fd);
    assert_close("γ vs d/dt f", gamma.as_slice(), &gamma_fd, 1e-11);
    for i in 0..nv {
        let col = central(
            &mut |h| {
                let mut vh = v.to_vec();
                vh[i] += h;
                f_at(q, &vh, t)
            },
            1e-3,
        );
        let ours: Vec<f64> = (0..nc).map(|r| j[(r, i)]).collect();
        worst = worst.max(rel_err(&ours, &col));
        assert_close(&format!("∂f/∂v[{i}]"), &ours, &col, 1e-11);
    }
    worst
}

#[test]
fn expression_rows_match_finite_differences() {
    // Floating base: configuration symbols on the position and the quaternion (q̇ = G(q) v
    // differs from v there), every function of the syntax, and time.
    let floating = r#"
  - name: mixed
    kind: velocity
    expression: "vz*cos(x) - 0.3*sqrt(vx^2 + vy^2 + 1)*exp(-t) + z*vy^3 + ln(2 + qz^2)*wz - abs(vx - 0.2)*tan(0.1*y) + wx*qw^2/(1.5 + sin(t))"
    variables: {x: "q:root_joint:x", y: "q:root_joint:y", z: "q:root_joint:z",
                qz: "q:root_joint:qz", qw: "q:root_joint:qw", vx: "v:root_joint:vx_local",
                vy: "v:root_joint:vy_local", vz: "v:root_joint:vz_local",
                wx: "v:root_joint:wx_local", wz: "v:root_joint:wz_local"}
"#;
    let mut sys = scene_from("point_mass.urdf", "floating", floating).unwrap();
    let (a, b, c) = (0.3f64, -0.4f64, 0.9f64); // a rotation, normalised below
    let n = (a * a + b * b + c * c + 1.0).sqrt();
    let q = [0.4, -1.1, 0.7, a / n, b / n, c / n, 1.0 / n];
    let v = [0.8, -0.5, 0.3, 1.2, -0.7, 0.9];
    let w1 = check_rows_against_differences(&mut sys, &q, &v, 0.37);
    // f itself, written out on (x, y, z, qx, qy, qz, qw) and (vx, vy, vz, wx, wy, wz): exmex
    // read `sqrt(vx^2 + vy^2 + 1)` as `vx^2 + sqrt(vy^2 + 1)`, which the differences above
    // could not see (its derivatives were those of the misread f).
    let t = 0.37f64;
    let f_hand = v[2] * q[0].cos() - 0.3 * (v[0] * v[0] + v[1] * v[1] + 1.0).sqrt() * (-t).exp()
        + q[2] * v[1].powi(3)
        + (2.0 + q[5] * q[5]).ln() * v[5]
        - (v[0] - 0.2).abs() * (0.1 * q[1]).tan()
        + v[3] * q[6] * q[6] / (1.5 + t.sin());
    sys.evaluate_rows(t, &q, &v);
    assert_close("f (floating)", sys.rows().jv.as_slice(), &[f_hand], 1e-15);
    // Planar base with a wheel angle and yaw (q̇ of x, y is the world velocity R(yaw) v).
    let planar = r#"
  - name: pursuit
    kind: velocity
    expression: "vx*cos(yaw) + vy*sin(yaw)^2 - 0.05*(wl + wr)*exp(0.1*x) + wz*y*t - left*0.01*wl^2"
    variables: {x: "q:root_joint:x", y: "q:root_joint:y", yaw: "q:root_joint:yaw",
                left: "q:left_wheel_joint", vx: "v:root_joint:vx_local",
                vy: "v:root_joint:vy_local", wz: "v:root_joint:wz", wl: "v:left_wheel_joint",
                wr: "v:right_wheel_joint"}
"#;
    let mut sys = scene_from("diff_drive.urdf", "planar", planar).unwrap();
    let q = [0.5, -0.3, 0.8, 1.3, -0.4];
    let v = [0.6, 0.2, -0.4, 3.0, 2.5];
    let w2 = check_rows_against_differences(&mut sys, &q, &v, 1.25);
    // f itself, the expression written out here on the model's coordinates (q: x, y, yaw,
    // left, right; v: vx, vy, wz, wl, wr): every symbol reads its own coordinate (the rows
    // above are checked against differences of f, which a symbol bound to the wrong
    // coordinate would pass).
    let t = 1.25f64;
    let f_hand = v[0] * q[2].cos() + v[1] * q[2].sin().powi(2)
        - 0.05 * (v[3] + v[4]) * (0.1 * q[0]).exp()
        + v[2] * q[1] * t
        - q[3] * 0.01 * v[3] * v[3];
    sys.evaluate_rows(t, &q, &v);
    assert_close("f (planar)", sys.rows().jv.as_slice(), &[f_hand], 1e-15); // achieved 0
    eprintln!("worst row difference: floating {w1:.2e}, planar {w2:.2e}");
}

// ---------------------------------------------------------------------------------------------
// Both forms, at states off the constraint too (Baumgarte on f itself).
// ---------------------------------------------------------------------------------------------

#[test]
fn multiplier_and_embedded_forms_agree_on_expression_scenes() {
    for rel in [
        "params/appell_hamel.yaml",
        "params/vertical_disk_expressions.yaml",
    ] {
        let sc = load(rel);
        let mut sys = System::from_scene(&sc).unwrap();
        sys = sys.with_baumgarte(Baumgarte::from_time_constant(0.05));
        let nv = sys.model().nv;
        for k in 0..4 {
            let x = k as f64;
            let v: Vec<f64> = sc
                .v0
                .iter()
                .enumerate()
                .map(|(i, vi)| vi + 0.1 * x * ((i as f64 + 1.0) * 1.3).sin())
                .collect();
            let tau: Vec<f64> = (0..nv)
                .map(|i| x * ((i as f64 + 1.0) * 0.7).cos())
                .collect();
            let a = sys
                .forward_dynamics(&sc.q0, &v, &tau, true)
                .unwrap()
                .clone();
            let f = sys.rows().jv.clone();
            let b = sys
                .forward_dynamics(&sc.q0, &v, &tau, false)
                .unwrap()
                .clone();
            // Achieved ≤ 2.8e-16 (q̈) and 8.4e-16 (the rows); the required bar is 1e-10.
            assert_close(
                &format!("{rel}[{k}] embedded vs multipliers"),
                b.as_slice(),
                a.as_slice(),
                5e-14,
            );
            // The acceleration rows hold with the Baumgarte term on f: J q̈ = −γ − K_d f.
            let jq = &sys.rows().j * &a;
            let rhs = -&sys.rows().gamma - f * sys.baumgarte().kd;
            assert_close(
                &format!("{rel}[{k}] J q̈ = −γ − K_d f"),
                jq.as_slice(),
                rhs.as_slice(),
                5e-14,
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Allocation-free evaluation.
// ---------------------------------------------------------------------------------------------

#[test]
fn expression_rows_do_not_allocate() {
    use constraint_dynamics::dynamics::constrained_forward_dynamics;
    for rel in [
        "params/appell_hamel.yaml",
        "params/vertical_disk_expressions.yaml",
    ] {
        let sc = load(rel);
        let mut sys = System::from_scene(&sc).unwrap();
        let tau = vec![0.1; sys.model().nv];
        let b = Baumgarte::from_time_constant(0.1);
        let (mut data, mut cd, mut kkt) = workspaces(&sys);
        let mut run = |sys: &mut System| {
            constrained_forward_dynamics(
                sys.model(),
                &mut data,
                sys.constraints(),
                &mut cd,
                &mut kkt,
                &sc.q0,
                &sc.v0,
                &tau,
                b,
            )
            .unwrap();
        };
        run(&mut sys);
        assert_eq!(allocations(|| run(&mut sys)), 0, "{rel}: allocates");
    }
}

// ---------------------------------------------------------------------------------------------
// Time reaches the rows in the predictor.
// ---------------------------------------------------------------------------------------------

/// A servo constraint vx = cos t on the floating ball (gravity along z, untouched): x(t) =
/// sin t, and the force that makes vx follow is m v̇x = λ ∂f/∂vx = λ, so λ = −m sin t.
/// A time that did not reach the rows would hold vx = cos 0 = 1. RK4's error here is O(dt⁴)
/// (dt = 1 ms): achieved x 5.1e-15, λ 0 (the same arithmetic as −sin t).
#[test]
fn time_dependent_expression_follows_its_schedule() {
    let decl = r#"
  - name: servo
    kind: velocity
    expression: "vx - cos(t)"
    variables: {vx: "v:root_joint:vx_local"}
"#;
    let sys = scene_from("point_mass.urdf", "floating", decl).unwrap();
    let mut p = Predictor::new(
        sys,
        Default::default(),
        Default::default(),
        Default::default(),
    )
    .unwrap()
    .with_settings(|s| {
        s.method = Method::Rk4;
        s.dt = 1e-3;
        s.drift = DriftControl::Projection;
        s.sample_period = 0.25;
    })
    .unwrap();
    let q0 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let v0 = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let traj = p
        .predict(&PredictionRequest::new(&q0, &v0).horizon(2.0).forces(true))
        .unwrap();
    let (mut wx, mut wl) = (0.0f64, 0.0f64);
    for s in &traj.samples {
        wx = wx.max((s.q[0] - s.t.sin()).abs());
        wl = wl.max((s.lambda.as_ref().unwrap()[0] + s.t.sin()).abs());
    }
    assert_close("servo x(t) = sin t", &[wx], &[0.0], 5e-13);
    assert_close("servo λ = −m sin t", &[wl], &[0.0], 1e-15);
}
