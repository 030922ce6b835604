//! The command-line tool, checked from outside: `constraint_dynamics eval` on a scene written for
//! the reference four-bar, at the reference states, prints q̈ and λ equal to Pinocchio's.

use crate::common;
use common::*;

fn eval(args: &[&str]) -> (bool, serde_json::Value, String) {
    let args: Vec<&str> = std::iter::once("eval")
        .chain(args.iter().copied())
        .collect();
    crate::run_cli(None, &args)
}

#[test]
fn eval_prints_reference_accelerations_and_multipliers() {
    let case = load_case("fourbar");
    let derivatives_ref: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(reference_dir().join("derivatives/fourbar.json")).unwrap(),
    )
    .unwrap();
    let dir = std::env::temp_dir().join(format!("cd_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let c = &case["constraints"][0];
    let a = vecf(&c["world_anchor"]);
    let scene = dir.join("fourbar.yaml");
    std::fs::write(
        &scene,
        format!(
            "urdf: {}\nconstraints:\n  - {{name: tip_at_D, kind: point, frame_a: tip, frame_b: world, point_b: [{}, {}, {}], rows: [x, z]}}\n",
            reference_dir().join("urdf/fourbar.urdf").display(),
            a[0],
            a[1],
            a[2]
        ),
    )
    .unwrap();
    for (k, st) in case["states"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .filter(|(_, s)| s.get("baumgarte").is_none())
    {
        let state = dir.join(format!("state{k}.json"));
        std::fs::write(
            &state,
            serde_json::json!({"q": st["q"], "v": st["qd"], "tau": st["tau"]}).to_string(),
        )
        .unwrap();
        let (ok, out, err) = eval(&[
            "--scene",
            scene.to_str().unwrap(),
            "--state",
            state.to_str().unwrap(),
            "--terms",
            "--derivatives",
        ]);
        assert!(ok, "eval failed: {err}");
        // The derivatives against Pinocchio's (../shared/reference/derivatives/fourbar.json, same
        // state order); the library reaches ≤ 3e-15 on the four-bar (tests/it/derivatives.rs).
        let dref = &derivatives_ref["states"][k]["expected"];
        let d = &out["derivatives"];
        for (ours, theirs) in [
            ("dqdd_dq", &dref["constrained"]["dqdd_dq"]),
            ("dqdd_dv", &dref["constrained"]["dqdd_dv"]),
            ("dqdd_dtau", &dref["constrained"]["dqdd_dtau"]),
            ("dlambda_dq", &dref["constrained"]["dlambda_dq"]),
            ("dlambda_dv", &dref["constrained"]["dlambda_dv"]),
            ("dlambda_dtau", &dref["constrained"]["dlambda_dtau"]),
            ("dtau_dq", &dref["unconstrained"]["dtau_dq"]),
            ("dtau_dv", &dref["unconstrained"]["dtau_dv"]),
        ] {
            let flat = |v: &serde_json::Value| -> Vec<f64> {
                v.as_array()
                    .unwrap_or_else(|| panic!("{ours}: not printed"))
                    .iter()
                    .flat_map(vecf)
                    .collect()
            };
            assert_close(
                &format!("cli fourbar[{k}] {ours}"),
                &flat(&d[ours]),
                &flat(theirs),
                2e-12,
            );
        }
        assert_eq!(out["q_names"], case["model"]["q_names"]);
        assert_close(
            &format!("cli fourbar[{k}] qdd"),
            &vecf(&out["qdd"]),
            &vecf(&st["expected"]["qdd"]),
            1e-9,
        );
        assert_close(
            &format!("cli fourbar[{k}] lambda"),
            &vecf(&out["lambda"]),
            &vecf(&st["expected"]["lambda"]),
            1e-9,
        );
        assert_close(
            &format!("cli fourbar[{k}] h"),
            &vecf(&out["h"]),
            &vecf(&st["debug_terms"]["h"]),
            1e-12,
        );
        let m: Vec<f64> = out["M"].as_array().unwrap().iter().flat_map(vecf).collect();
        let m_ref: Vec<f64> = st["debug_terms"]["M"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(vecf)
            .collect();
        assert_close(&format!("cli fourbar[{k}] M"), &m, &m_ref, 1e-12);
        assert_eq!(out["constraints"][0]["name"], "tip_at_D");
        assert_eq!(out["constraints"][0]["rows"], serde_json::json!(["x", "z"]));
    }
}

#[test]
fn eval_reports_bad_input_with_a_message_and_exit_code() {
    let (ok, _, err) = eval(&["--scene", "/nonexistent/scene.yaml"]);
    assert!(
        !ok && err.contains("/nonexistent/scene.yaml") && err.contains("cannot read"),
        "{err}"
    );
    let dir = std::env::temp_dir().join(format!("cd_cli_bad_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let state = dir.join("short.json");
    std::fs::write(&state, r#"{"q": [0.1, 0.2]}"#).unwrap();
    let scene = repo_dir().join("params/fourbar.yaml");
    let (ok, _, err) = eval(&[
        "--scene",
        scene.to_str().unwrap(),
        "--state",
        state.to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("q: expected 3 values, got 2"), "{err}");
}

/// `kind: velocity` through the binary: λ of Appell–Hamel's ż = a √(ẋ² + ẏ²) at
/// the scene's state is m g/(1 + a²) (closed form, docs/nonholonomic.md), and the generalized
/// force (∂f/∂v)ᵀλ = λ (−a ẋ/s, −a ẏ/s, 1) on (vx_local, vy_local, vz_local), in N.
#[test]
fn eval_reports_velocity_constraint_forces_with_units() {
    let (a, g, m) = (0.5, 9.81, 1.0);
    let scene = repo_dir().join("params/appell_hamel.yaml");
    let (ok, out, err) = eval(&["--scene", scene.to_str().unwrap()]);
    assert!(ok, "{err}");
    let lam = m * g / (1.0 + a * a);
    let c = &out["constraints"][0];
    assert_eq!(c["kind"], "velocity");
    assert_eq!(c["rows"], serde_json::json!(["f"]));
    assert_close("λ", &vecf(&c["lambda"]), &[lam], 1e-15); // achieved 1.1e-16
    let gf = c["generalized_force"].as_array().unwrap();
    let names: Vec<&str> = gf
        .iter()
        .map(|e| e["coordinate"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "root_joint:vx_local",
            "root_joint:vy_local",
            "root_joint:vz_local"
        ]
    );
    assert!(gf.iter().all(|e| e["unit"] == "N"));
    let values: Vec<f64> = gf.iter().map(|e| e["value"].as_f64().unwrap()).collect();
    // ẋ/s, ẏ/s = 0.8, 0.6 at the scene's state; achieved 1.1e-16.
    assert_close(
        "(∂f/∂v)ᵀλ",
        &values,
        &[-a * 0.8 * lam, -a * 0.6 * lam, lam],
        1e-15,
    );
    assert_close(
        "f at the scene's state",
        &vecf(&c["velocity_residual"]),
        &[0.0],
        1e-15,
    );
}
