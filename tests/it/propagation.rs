//! Propagation against independent numbers: one semi-implicit Euler step of every reference state
//! (Pinocchio's `integrate` on SE(3) for the free-flyer cases), and the reference's rolling-disk
//! energy-drift run.

use crate::common;
use common::*;
use constraint_dynamics::System;
use constraint_dynamics::actuators::Actuators;
use constraint_dynamics::constraints::ConstraintSet;
use constraint_dynamics::dynamics::{Baumgarte, Formulation};
use constraint_dynamics::forces::ForceElements;
use constraint_dynamics::predict::{
    DriftControl, IntegrationOverrides, IntegrationSettings, Method, PredictionRequest, Predictor,
};

/// The system of reference state `k` of case `name`, integration settings by `method` at `dt`
/// without drift control, and the state's q and v.
fn parts_for(
    name: &str,
    k: usize,
    method: Method,
    dt: f64,
) -> (System, IntegrationSettings, Vec<f64>, Vec<f64>) {
    let case = load_case(name);
    let model = case_model(&case);
    let st = &case["states"][k];
    let q = vecf(&st["q"]);
    let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
    let b = st
        .get("baumgarte")
        .map_or(Baumgarte::default(), |b| Baumgarte {
            kp: b["Kp"].as_f64().unwrap(),
            kd: b["Kd"].as_f64().unwrap(),
        });
    let sys = System::new(model, set, b, Formulation::Multipliers);
    let settings = IntegrationSettings {
        method,
        dt,
        drift: DriftControl::None,
        sample_period: dt,
        ..Default::default()
    };
    (sys, settings, q, vecf(&st["qd"]))
}

fn predictor_for(name: &str, k: usize, method: Method, dt: f64) -> (Predictor, Vec<f64>, Vec<f64>) {
    let (sys, settings, q, v) = parts_for(name, k, method, dt);
    let p = Predictor::new(
        sys,
        ForceElements::default(),
        Actuators::default(),
        settings,
    )
    .unwrap();
    (p, q, v)
}

#[test]
fn semi_implicit_euler_step_matches_reference_on_every_state() {
    for name in [
        "fourbar",
        "ur5_ee_point",
        "solo12_four_feet",
        "rolling_disk",
    ] {
        let case = load_case(name);
        for (k, st) in case["states"].as_array().unwrap().iter().enumerate() {
            let tau = vecf(&st["tau"]);
            if tau.iter().any(|t| *t != 0.0) {
                // The reference steps use the state's τ; the predictor's τ comes from force elements.
                let (sys, settings, q, v) = parts_for(name, k, Method::SemiImplicitEuler, 1.0);
                let mut fe_spec = constraint_dynamics::forces::ForcesSpec::default();
                for (i, &t) in tau.iter().enumerate() {
                    if t != 0.0 {
                        fe_spec
                            .joint_torques
                            .push(constraint_dynamics::forces::JointTorqueSpec {
                                joint: sys.model().v_names[i].clone(),
                                value: t,
                                profile: vec![],
                            });
                    }
                }
                if sys.model().base == constraint_dynamics::BaseType::Floating
                    && tau[..6].iter().any(|t| *t != 0.0)
                {
                    continue; // base wrenches are not joint torques
                }
                let forces = ForceElements::new(sys.model(), &fe_spec).unwrap();
                let mut p = Predictor::new(sys, forces, Actuators::default(), settings).unwrap();
                check_step(&mut p, &q, &v, st, &format!("{name}[{k}]"));
            } else {
                let (mut p, q, v) = predictor_for(name, k, Method::SemiImplicitEuler, 1.0);
                check_step(&mut p, &q, &v, st, &format!("{name}[{k}]"));
            }
        }
    }
}

fn check_step(p: &mut Predictor, q: &[f64], v: &[f64], st: &serde_json::Value, tag: &str) {
    let e = &st["expected"]["semi_implicit_euler"];
    let dt = e["dt"].as_f64().unwrap();
    let step = IntegrationOverrides {
        dt: Some(dt),
        sample_period: Some(dt),
        ..Default::default()
    };
    let traj = p
        .predict(&PredictionRequest::new(q, v).horizon(dt).integration(step))
        .unwrap();
    let last = traj.samples.last().unwrap();
    assert_close(
        &format!("{tag} qd_next"),
        &last.v,
        &vecf(&e["qd_next"]),
        1e-13, // achieved ≤ 1.7e-15 (Solo12) over all 17 states
    );
    assert_close(
        &format!("{tag} q_next"),
        &last.q,
        &vecf(&e["q_next"]),
        1e-14, // achieved ≤ 1.1e-16 (Pinocchio's integrate on SE(3) for the free-flyer cases)
    );
}

// Against the reference run (absolute, printed by `assert_close`): the initial energy is
// exact (achieved 0; floor 1e-15); the max energy drift agrees to 9.2e-14 J (tol 5e-12); the
// max |J q̇| to 9.7e-7 m/s, 0.09 % of the reference's 1.04e-3 m/s while the energy agrees to
// 1e-13 — a difference in where within the step the residual is sampled is the likely cause,
// not verified here (tol 1e-5, 10×).
const T_E0: f64 = 1e-15;
const T_DRIFT: f64 = 5e-12;
const T_JQD: f64 = 1e-5;

#[test]
fn rolling_disk_energy_drift_matches_the_reference_run() {
    // Reference: from state 1, 2 s, dt = 1e-4, semi-implicit Euler, Baumgarte Kp = 100, Kd = 20:
    // max |ΔE| = 0.021630386769942556 J, max |J q̇| = 0.0010381908883498713 m/s.
    let case = load_case("rolling_disk");
    let chk = &case["simulation_energy_check"];
    let (mut sys, settings, q, v) = parts_for("rolling_disk", 1, Method::SemiImplicitEuler, 1e-4);
    sys = sys.with_baumgarte(Baumgarte {
        kp: 100.0,
        kd: 20.0,
    });
    let mut p = Predictor::new(
        sys,
        ForceElements::default(),
        Actuators::default(),
        settings,
    )
    .unwrap()
    .with_settings(|s| {
        s.sample_period = 1e-4;
        // The reference is a coarse first-order run, reproduced as it is: its global error
        // passes the default max_error (1e-3) at t = 0.245 s, so the bound is off for this
        // comparison.
        s.max_error = f64::INFINITY;
    })
    .unwrap();
    let horizon = chk["duration_s"].as_f64().unwrap();
    let traj = p
        .predict(&PredictionRequest::new(&q, &v).horizon(horizon))
        .unwrap();
    let e0 = chk["initial_energy_J"].as_f64().unwrap();
    let s0 = &traj.samples[0];
    assert_close(
        "initial energy",
        &[s0.kinetic_energy + s0.potential_energy],
        &[e0],
        T_E0,
    );
    let drift = traj
        .samples
        .iter()
        .map(|s| (s.kinetic_energy + s.potential_energy - e0).abs())
        .fold(0.0, f64::max);
    let jqd = traj
        .samples
        .iter()
        .map(|s| s.velocity_residual)
        .fold(0.0, f64::max);
    let (drift_ref, jqd_ref) = (
        chk["max_abs_energy_drift_J"].as_f64().unwrap(),
        chk["max_abs_Jqd_m_per_s"].as_f64().unwrap(),
    );
    // The same 20 000 steps as the reference run, so the two agree to round-off accumulated over
    // the run, not to the method's error.
    assert_close("max |ΔE| [J]", &[drift], &[drift_ref], T_DRIFT);
    assert_close("max |J q̇| [m/s]", &[jqd], &[jqd_ref], T_JQD);
}
