//! The `project` subcommand end to end (the binary, JSON on stdout, a request file, bad input).

use crate::common;

use common::*;
use serde_json::Value;

#[test]
fn cli_project_prints_the_result_as_json() {
    let bin = env!("CARGO_BIN_EXE_constraint_dynamics");
    let scene = repo_dir().join("params/diff_drive.yaml");
    let run = |req: &str| {
        let out = std::process::Command::new(bin)
            .args(["project", "--scene"])
            .arg(&scene)
            .args(["--v-des", req])
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).to_string(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    let (ok, stdout, stderr) =
        run(r#"{"base_twist": [1.0, 0.0, 0.5], "upper": {"right_wheel_joint": 10.0}}"#);
    assert!(ok, "{stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["status"], "optimal");
    assert_eq!(v["active_bounds"][0]["coordinate"], "right_wheel_joint");
    assert_eq!(v["base_twist"].as_array().unwrap().len(), 3);
    assert_eq!(v["constraints"][0]["name"], "left_wheel_contact");
    // A request file.
    let file = std::env::temp_dir().join(format!("cd_project_{}.json", std::process::id()));
    std::fs::write(&file, r#"{"v_des": [0.2, 0.0, 0.0, 4.0, 4.0]}"#).unwrap();
    let (ok, stdout, stderr) = run(file.to_str().unwrap());
    std::fs::remove_file(&file).ok();
    assert!(ok, "{stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    // achieved 0 (the request is feasible: returned as is); floor 1e-15
    assert_close(
        "feasible request unchanged",
        &vecf(&v["v"]),
        &[0.2, 0.0, 0.0, 4.0, 4.0],
        1e-15,
    );
    // Bad input: a clear error, non-zero exit.
    let (ok, _, stderr) = run(r#"{"joints": {"wheel": 1.0}}"#);
    assert!(
        !ok && stderr.contains("unknown velocity coordinate 'wheel'"),
        "{stderr}"
    );
}

/// `--period`: from rest, the cart (tests/data/cart_tall_mass.yaml) asked far ahead gains
/// Δt × its effort-limited acceleration 2 τ_max / (r (M + 2 I_w / r²)) (docs/projection.md,
/// the envelope's closed forms: τ_max 4 N·m, r 0.1 m, M 32.5 kg, I_w 0.005 kg·m²) and names
/// both wheels' efforts; an out-of-reach bound is infeasible and says why; `--period 0` prints
/// exactly what no period prints.
#[test]
fn cli_project_with_a_period_respects_the_dynamics() {
    let bin = env!("CARGO_BIN_EXE_constraint_dynamics");
    let scene = repo_dir().join("tests/data/cart_tall_mass.yaml");
    let run = |req: &str, period: Option<&str>| {
        let mut cmd = std::process::Command::new(bin);
        cmd.args(["project", "--scene"])
            .arg(&scene)
            .args(["--v-des", req]);
        if let Some(p) = period {
            cmd.arg(format!("--period={p}"));
        }
        let out = cmd.output().unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).to_string(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    let ahead = r#"{"base_twist": [50.0, 0, 0, 0, 0, 0]}"#;
    let (ok, stdout, stderr) = run(ahead, Some("0.01"));
    assert!(ok, "{stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["status"], "optimal");
    assert_eq!(v["method"], "dynamic");
    let expect = 0.01 * 2.0 * 4.0 / (0.1 * (32.5 + 2.0 * 0.005 / 0.01));
    let got = v["base_twist"][0].as_f64().unwrap();
    assert!((got - expect).abs() < 1e-6 * expect, "{got} vs {expect}");
    let binding: Vec<(String, String)> = v["dynamics"]["binding"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            (
                b["kind"].as_str().unwrap().into(),
                b["name"].as_str().unwrap().into(),
            )
        })
        .collect();
    assert_eq!(
        binding,
        [
            ("effort".to_string(), "left_wheel_joint".to_string()),
            ("effort".to_string(), "right_wheel_joint".to_string())
        ]
    );
    assert_eq!(v["dynamics"]["period"], 0.01);
    assert_eq!(v["dynamics"]["tau"].as_array().unwrap().len(), 2);
    // Out of reach: braking to −0.1 m/s in 10 ms; the caster would lift off.
    let (ok, stdout, stderr) = run(
        r#"{"base_twist": [0, 0, 0, 0, 0, 0], "upper": {"vx": -0.1}}"#,
        Some("0.01"),
    );
    assert!(ok, "{stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["status"], "infeasible");
    let msg = v["message"].as_str().unwrap();
    assert!(
        msg.contains("caster_contact") && msg.contains("vx_local <= -0.1"),
        "{msg}"
    );
    assert!(v.get("v").is_none());
    // Period 0 is the kinematic projection, and so is no period.
    let (_, with_zero, _) = run(ahead, Some("0"));
    let (_, without, _) = run(ahead, None);
    assert_eq!(with_zero, without);
    assert!(!with_zero.contains("dynamics"));
    // A negative period is refused.
    let (ok, _, stderr) = run(ahead, Some("-0.01"));
    assert!(!ok && stderr.contains("period"), "{stderr}");
}

/// A wheel whose sideways grip is a tyre's (`lateral: tyre`) creeps sideways only under the
/// force the tyre gives over time: the projection, an instantaneous answer, holds it rigid
/// sideways, so a diff drive asked to slide sideways is given none of it; the envelope answers
/// on the same scene.
#[test]
fn cli_project_holds_sideways_tyres_rigid() {
    let scene = repo_dir().join("tests/data/diff_drive_sideways_tyres.yaml");
    let scene = scene.to_str().unwrap();
    let req = r#"{"base_twist": [0.5, 0.3, 0.4]}"#;
    let (ok, v, err) = crate::run_cli(None, &["project", "--scene", scene, "--v-des", req]);
    assert!(ok && v["status"] == "optimal", "{err}");
    let twist = vecf(&v["base_twist"]);
    assert!(twist[1].abs() < 1e-12, "sideways {twist:?}");
    assert!(
        (twist[0] - 0.5).abs() < 1e-9 && (twist[2] - 0.4).abs() < 1e-9,
        "{twist:?}"
    );
    let (ok, envelope, err) = crate::run_cli(None, &["envelope", "--scene", scene]);
    assert!(ok, "{err}");
    assert!(
        envelope["forward_acceleration"]["max"].as_f64().unwrap() > 0.0,
        "{envelope}"
    );
}
