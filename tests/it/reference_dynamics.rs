//! q̈ and λ of all four reference cases (Pinocchio 4.1.0 dense KKT, `../shared/reference/cases/`),
//! Baumgarte states included, by both formulations (λ only from the multiplier form).
//!
//! Tolerances (relative to max(1, max |ref|), `common::rel_err`) are set from the achieved
//! figures, printed by `assert_close` (`-- --nocapture`), with a margin of 10–100×:
//! q̈ reaches ≤ 2.7e-15 on fourbar, UR5 and the disk (tol 1e-13) and 1.2e-12 on Solo12, whose
//! reference itself spreads by up to 2.1e-12 between Pinocchio's solvers (`crosschecks_maxabs`,
//! tol 5e-11); λ ≤ 3.0e-15 everywhere (tol 1e-13); φ ≤ 5.6e-17 (tol 2e-15).
//!
//! Conventions are the reference's: λ is the force ON the robot in world axes; the rolling disk's
//! rows are world x, y, z, which is our (t₁, t₂, n) basis for the plane normal +z.

use crate::common;
use common::*;
use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet};
use constraint_dynamics::dynamics::*;

/// `qdd_tol`: the case's tolerance on q̈ (see the header).
fn check(name: &str, qdd_tol: f64) {
    let case = load_case(name);
    let model = case_model(&case);
    let mut data = Data::new(&model);
    for (k, st) in case["states"].as_array().unwrap().iter().enumerate() {
        let q = vecf(&st["q"]);
        let v = vecf(&st["qd"]);
        let tau = vecf(&st["tau"]);
        let stab = st
            .get("baumgarte")
            .map_or(Baumgarte::default(), |b| Baumgarte {
                kp: b["Kp"].as_f64().unwrap(),
                kd: b["Kd"].as_f64().unwrap(),
            });
        let set = ConstraintSet::new(&model, &specs_for(&case, st), &q).unwrap();
        let mut cd = ConstraintData::new(&model, &set);
        let mut ws = KktWorkspace::new(&model, &set);
        constrained_forward_dynamics(
            &model, &mut data, &set, &mut cd, &mut ws, &q, &v, &tau, stab,
        )
        .unwrap();
        let exp = &st["expected"];
        let tag = format!(
            "{name}[{k}]{}",
            if st.get("baumgarte").is_some() {
                " (Baumgarte)"
            } else {
                ""
            }
        );
        assert_close(
            &format!("{tag} qdd"),
            ws.qdd.as_slice(),
            &vecf(&exp["qdd"]),
            qdd_tol,
        );
        assert_close(
            &format!("{tag} lambda"),
            ws.lambda.as_slice(),
            &vecf(&exp["lambda"]),
            1e-13,
        );
        assert_close(
            &format!("{tag} phi"),
            cd.phi.as_slice(),
            &vecf(&st["debug_terms"]["phi"]),
            2e-15,
        );

        let mut ew = EmbeddedWorkspace::default();
        embedded_forward_dynamics(
            &model, &mut data, &set, &mut cd, &mut ew, &q, &v, &tau, 0.0, stab,
        )
        .unwrap();
        // The two formulations against each other: ≤ 4.8e-15, Solo12 1.2e-12 (as q̈ above).
        assert_close(
            &format!("{tag} embedded qdd"),
            ew.qdd.as_slice(),
            ws.qdd.as_slice(),
            qdd_tol,
        );
    }
}

#[test]
fn fourbar_matches_reference() {
    check("fourbar", 1e-13);
}

#[test]
fn ur5_ee_point_matches_reference() {
    check("ur5_ee_point", 1e-13);
}

#[test]
fn solo12_four_feet_matches_reference() {
    check("solo12_four_feet", 5e-11);
}

#[test]
fn rolling_disk_matches_reference() {
    check("rolling_disk", 1e-13);
}
