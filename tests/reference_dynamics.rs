//! q̈ and λ of all four reference cases (Pinocchio 4.1.0 dense KKT) to 1e-9 relative, Baumgarte
//! states included, by both formulations (λ only from the multiplier form).
//!
//! Conventions are the reference's: λ is the force ON the robot in world axes; the rolling disk's
//! rows are world x, y, z, which is our (t₁, t₂, n) basis for the plane normal +z.

mod common;
use common::*;
use constraint_dynamics::algorithm::Data;
use constraint_dynamics::constraints::{ConstraintData, ConstraintSet, ConstraintSpec, Row};
use constraint_dynamics::dynamics::*;
use serde_json::Value;

fn specs_for(case: &Value, st: &Value) -> Vec<ConstraintSpec> {
    let cons = st.get("constraints").unwrap_or(&case["constraints"]);
    cons.as_array()
        .unwrap()
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let link = c["link"].as_str().unwrap().to_string();
            match c["type"].as_str().unwrap() {
                "point_fixed_in_world" => {
                    let a = vecf(&c["world_anchor"]);
                    let rows = c["rows"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|r| match r.as_str().unwrap() {
                            "x" => Row::X,
                            "y" => Row::Y,
                            _ => Row::Z,
                        })
                        .collect();
                    ConstraintSpec::Point {
                        name: format!("c{k}"),
                        frame_a: link,
                        point_a: [0.0; 3],
                        frame_b: "world".into(),
                        point_b: [a[0], a[1], a[2]],
                        rows,
                    }
                }
                "rolling_disk_on_plane_z0" => {
                    let ax = vecf(&c["disk_axis_in_body"]);
                    ConstraintSpec::Rolling {
                        name: format!("c{k}"),
                        wheel: link,
                        axis: [ax[0], ax[1], ax[2]],
                        radius: c["radius"].as_f64().unwrap(),
                        plane_normal: [0.0, 0.0, 1.0],
                        plane_height: 0.0,
                    }
                }
                t => panic!("unknown reference constraint type {t}"),
            }
        })
        .collect()
}

fn check(name: &str) {
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
            1e-9,
        );
        assert_close(
            &format!("{tag} lambda"),
            ws.lambda.as_slice(),
            &vecf(&exp["lambda"]),
            1e-9,
        );
        assert_close(
            &format!("{tag} phi"),
            cd.phi.as_slice(),
            &vecf(&st["debug_terms"]["phi"]),
            1e-12,
        );

        let mut ew = EmbeddedWorkspace::default();
        embedded_forward_dynamics(
            &model, &mut data, &set, &mut cd, &mut ew, &q, &v, &tau, stab,
        )
        .unwrap();
        assert_close(
            &format!("{tag} embedded qdd"),
            ew.qdd.as_slice(),
            ws.qdd.as_slice(),
            1e-10,
        );
    }
}

#[test]
fn fourbar_matches_reference() {
    check("fourbar");
}

#[test]
fn ur5_ee_point_matches_reference() {
    check("ur5_ee_point");
}

#[test]
fn solo12_four_feet_matches_reference() {
    check("solo12_four_feet");
}

#[test]
fn rolling_disk_matches_reference() {
    check("rolling_disk");
}
