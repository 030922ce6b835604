//! `kind: velocity` with `dependent:` — the embedded (multiplier-free) form takes the named
//! velocities as the dependent ones and solves them from f = 0 by Newton (seed 001, eq. 2),
//! against Appell–Hamel's closed forms (docs/nonholonomic.md) and the multiplier form.

use crate::common;
use common::*;
use constraint_dynamics::dynamics::Formulation;
use constraint_dynamics::predict::{DriftControl, Method, PredictionRequest, Predictor};
use constraint_dynamics::{Error, Scene, System};

const A: f64 = 0.5;

/// params/appell_hamel.yaml with `dependent: [sym]` added to its constraint.
fn appell_hamel_with(dependent: &str) -> Scene {
    let text = std::fs::read_to_string(repo_dir().join("params/appell_hamel.yaml")).unwrap();
    let text = text
        .replace("../urdf/", &format!("{}/urdf/", repo_dir().display()))
        .replace(
            "    virtual_displacements: chetaev\n",
            &format!("    virtual_displacements: chetaev\n    dependent: [{dependent}]\n"),
        );
    assert!(text.contains("dependent:"));
    // One file per call: the tests run in parallel threads of one process.
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let path = std::env::temp_dir().join(format!(
        "velocity_dependent_{dependent}_{}_{}.yaml",
        std::process::id(),
        N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    std::fs::write(&path, text).unwrap();
    let sc = Scene::load(&path);
    let _ = std::fs::remove_file(&path);
    sc.unwrap()
}

#[test]
fn declared_dependent_velocity_is_the_partitions() {
    // Unforced, the best-conditioned column is vz (|∂f/∂vz| = 1 > a·0.8, a·0.6); naming vx
    // changes the choice, naming vz keeps it.
    for (sym, idx) in [("vz", 2usize), ("vx", 0)] {
        let sc = appell_hamel_with(sym);
        let mut sys = System::from_scene(&sc).unwrap();
        sys.forward_dynamics(&sc.q0, &sc.v0, &[0.0; 6], false)
            .unwrap();
        assert_eq!(sys.last_formulation(), Formulation::Embedded);
        assert_eq!(
            sys.embedded().partition.dependent,
            [idx],
            "dependent: [{sym}]"
        );
    }
    let sc = load_plain();
    let mut sys = System::from_scene(&sc).unwrap();
    sys.forward_dynamics(&sc.q0, &sc.v0, &[0.0; 6], false)
        .unwrap();
    assert_eq!(sys.embedded().partition.dependent, [2]);
    assert!(sys.embedded().solved_velocities().is_none());
}

fn load_plain() -> Scene {
    Scene::load(repo_dir().join("params/appell_hamel.yaml")).unwrap()
}

/// Off the constraint, the named velocity is solved from f = 0 (closed forms: vz = a s, or
/// vx = √((vz/a)² − vy²) on the branch Newton starts on), and q̈ equals the multiplier form's
/// at that solved state.
#[test]
fn dependent_velocities_are_solved_from_f_by_newton() {
    let q = load_plain().q0;
    let v_off: [f64; 6] = [7.0, 6.5, 4.0, 0.0, 0.0, 0.0];
    let tau = [0.3, -0.2, 0.1, 0.0, 0.0, 0.0];
    let (vx, vy, vz) = (v_off[0], v_off[1], v_off[2]);
    let s = (vx * vx + vy * vy).sqrt();
    for (sym, expected) in [
        ("vz", [vx, vy, A * s, 0.0, 0.0, 0.0]),
        (
            "vx",
            [((vz / A).powi(2) - vy * vy).sqrt(), vy, vz, 0.0, 0.0, 0.0],
        ),
    ] {
        let sc = appell_hamel_with(sym);
        let mut sys = System::from_scene(&sc).unwrap();
        let a_emb = sys
            .forward_dynamics(&q, &v_off, &tau, false)
            .unwrap()
            .clone();
        let solved = sys.embedded().solved_velocities().unwrap().to_vec();
        // Achieved 0 (vz) and 5.5e-15 (vx: Newton stops at |f| ≤ 1e-14 · max(1, |v_d|)).
        assert_close(&format!("{sym} solved from f"), &solved, &expected, 5e-14);
        let a_mul = sys
            .forward_dynamics(&q, &solved, &tau, true)
            .unwrap()
            .clone();
        // Achieved 0 (vz) and 6.6e-16 (vx).
        assert_close(
            &format!("{sym}: embedded at v_off = multipliers at the solved v"),
            a_emb.as_slice(),
            a_mul.as_slice(),
            1e-13,
        );
    }
    // No solution: vz/a < |vy| leaves no real vx.
    let sc = appell_hamel_with("vx");
    let mut sys = System::from_scene(&sc).unwrap();
    match sys.forward_dynamics(&q, &[1.0, 6.0, 1.0, 0.0, 0.0, 0.0], &tau, false) {
        Err(Error::InconsistentConstraints { message })
        | Err(Error::Constraint { message, .. }) => {
            assert!(message.contains("lift_with_speed"), "{message}")
        }
        other => panic!("{other:?}"),
    }
}

/// The embedded propagation with vz dependent follows the closed form too (achieved q 5.3e-14,
/// v 2.0e-13 over 2 s; the required bar is 1e-9).
#[test]
fn embedded_propagation_with_dependent_velocity_follows_the_closed_form() {
    let (g, s0, z0) = (9.81, 10.0, 1.0);
    let mut sc = appell_hamel_with("vz");
    sc.file.dynamics.formulation = Formulation::Embedded;
    let mut p = Predictor::from_scene(&sc)
        .unwrap()
        .with_settings(|s| {
            s.method = Method::Rk4;
            s.dt = 1e-3;
            s.drift = DriftControl::Projection;
            s.sample_period = 0.1;
        })
        .unwrap();
    let traj = p
        .predict(&PredictionRequest::new(&sc.q0, &sc.v0).horizon(2.0))
        .unwrap();
    let sd = -g * A / (1.0 + A * A);
    let (mut wq, mut wv) = (0.0f64, 0.0f64);
    for smp in &traj.samples {
        let t = smp.t;
        let (s, d) = (s0 + sd * t, s0 * t + 0.5 * sd * t * t);
        wq = wq.max(rel_err(
            &smp.q,
            &[0.8 * d, 0.6 * d, z0 + A * d, 0.0, 0.0, 0.0, 1.0],
        ));
        wv = wv.max(rel_err(&smp.v, &[0.8 * s, 0.6 * s, A * s, 0.0, 0.0, 0.0]));
    }
    assert_close("embedded, vz dependent: q", &[wq], &[0.0], 1e-11);
    assert_close("embedded, vz dependent: v", &[wv], &[0.0], 1e-11);
}
