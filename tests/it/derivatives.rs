//! Analytic derivatives against Pinocchio 4.1.0's (`../shared/reference/derivatives/`, checked
//! there by Richardson-extrapolated finite differences of an independent dense KKT solve):
//! inverse dynamics ∂τ/∂q, ∂τ/∂v and M; forward dynamics ∂q̈/∂q, ∂q̈/∂v and M⁻¹; the
//! constrained dynamics' ∂q̈ and ∂λ with respect to q, v and τ (Baumgarte states included).
//!
//! Error measure: max |X − X_ref| / max |X_ref| per matrix (the reference README's). Tolerances
//! from the achieved figures printed by `--nocapture`, with a margin of about 100×: see the
//! constants.

use crate::common;
use common::*;
use constraint_dynamics::algorithm::{Data, crba_full};
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::derivatives::*;
use constraint_dynamics::dynamics::{Baumgarte, KktWorkspace};
use nalgebra::DMatrix;
use serde_json::Value;

/// Unconstrained (RNEA, ABA, M, M⁻¹): achieved ≤ 1.2e-14 (Solo12), 3.4e-15 (UR5), 1.7e-15
/// (four-bar); the reference suggests 1e-10.
const TOL_FREE: f64 = 1e-12;
/// Constrained (∂q̈, ∂λ): achieved ≤ 1.8e-14 (Solo12), 1.4e-14 (UR5), 2.9e-15 (four-bar); the
/// reference suggests 1e-8.
const TOL_CONSTRAINED: f64 = 2e-12;

fn load_derivatives(name: &str) -> Value {
    let p = reference_dir()
        .join("derivatives")
        .join(format!("{name}.json"));
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&text).unwrap()
}

/// max |a − b| / max |b|.
fn matrix_err(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    assert_eq!(a.shape(), b.shape(), "shape");
    let scale = b.amax().max(f64::MIN_POSITIVE);
    (a - b).amax() / scale
}

fn check_matrix(what: &str, ours: &DMatrix<f64>, reference: &Value, tol: f64) -> f64 {
    let r = dmat(reference);
    let e = matrix_err(ours, &r);
    eprintln!("achieved {what}: {e:.2e} (tol {tol:.0e})");
    assert!(
        e <= tol,
        "{what}: relative error {e:.3e} > {tol:.1e}\n ours: {ours:.6}\n  ref: {r:.6}"
    );
    e
}

fn check(name: &str) {
    let reference = load_derivatives(name);
    let case = load_case(name);
    let model = case_model(&case);
    let mut data = Data::new(&model);
    let (mut worst_free, mut worst_con) = (0.0f64, 0.0f64);
    for (k, st) in reference["states"].as_array().unwrap().iter().enumerate() {
        let tag = format!("{name}[{k}]");
        let (q, v, tau) = (vecf(&st["q"]), vecf(&st["qd"]), vecf(&st["tau"]));
        let free = &st["expected"]["unconstrained"];
        let mut dd = DerivativeData::new(&model, 0);

        rnea_derivatives(
            &model,
            &mut data,
            &mut dd,
            &q,
            &v,
            &vecf(&free["a_used_for_rnea"]),
        );
        worst_free = worst_free
            .max(check_matrix(
                &format!("{tag} dtau_dq"),
                &dd.dtau_dq,
                &free["dtau_dq"],
                TOL_FREE,
            ))
            .max(check_matrix(
                &format!("{tag} dtau_dv"),
                &dd.dtau_dv,
                &free["dtau_dv"],
                TOL_FREE,
            ));
        crba_full(&model, &mut data, &q);
        let m = data.mass_matrix.clone();
        worst_free = worst_free.max(check_matrix(&format!("{tag} M"), &m, &free["M"], TOL_FREE));

        aba_derivatives(&model, &mut data, &mut dd, &q, &v, &tau).unwrap();
        assert_close(
            &format!("{tag} qdd_free"),
            dd.qdd.as_slice(),
            &vecf(&free["qdd_free_aba"]),
            1e-12,
        );
        worst_free = worst_free
            .max(check_matrix(
                &format!("{tag} dqdd_dq (free)"),
                &dd.dqdd_dq,
                &free["dqdd_dq"],
                TOL_FREE,
            ))
            .max(check_matrix(
                &format!("{tag} dqdd_dv (free)"),
                &dd.dqdd_dv,
                &free["dqdd_dv"],
                TOL_FREE,
            ))
            .max(check_matrix(
                &format!("{tag} Minv"),
                &dd.minv,
                &free["Minv"],
                TOL_FREE,
            ));

        let con = &st["expected"]["constrained"];
        let stab = st
            .get("baumgarte")
            .map_or(Baumgarte::default(), |b| Baumgarte {
                kp: b["Kp"].as_f64().unwrap(),
                kd: b["Kd"].as_f64().unwrap(),
            });
        let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
        let mut cd = ConstraintData::new(&model, &set);
        let mut ws = KktWorkspace::new(&model, &set);
        let mut dd = DerivativeData::new(&model, set.nrows);
        constrained_dynamics_derivatives(
            &model, &mut data, &set, &mut cd, &mut ws, &mut dd, &q, &v, &tau, stab,
        )
        .unwrap();
        assert!(
            dd.lambda_unique,
            "{tag}: J has full row rank in every reference state"
        );
        assert_close(
            &format!("{tag} qdd"),
            dd.qdd.as_slice(),
            &vecf(&con["qdd"]),
            1e-11,
        );
        for (what, ours) in [
            ("dqdd_dq", &dd.dqdd_dq),
            ("dqdd_dv", &dd.dqdd_dv),
            ("dqdd_dtau", &dd.dqdd_dtau),
            ("dlambda_dq", &dd.dlambda_dq),
            ("dlambda_dv", &dd.dlambda_dv),
            ("dlambda_dtau", &dd.dlambda_dtau),
        ] {
            worst_con = worst_con.max(check_matrix(
                &format!("{tag} {what}"),
                ours,
                &con[what],
                TOL_CONSTRAINED,
            ));
        }
    }
    eprintln!("{name}: worst unconstrained {worst_free:.2e}, worst constrained {worst_con:.2e}");
}

#[test]
fn fourbar_derivatives_match_pinocchio() {
    check("fourbar");
}

#[test]
fn ur5_derivatives_match_pinocchio() {
    check("ur5_ee_point");
}

#[test]
fn solo12_derivatives_match_pinocchio() {
    check("solo12_four_feet");
}
