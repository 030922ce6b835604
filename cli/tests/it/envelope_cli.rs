//! The `envelope` subcommand end to end (the binary, JSON on stdout, a state file, bad input).

use crate::common;

use common::*;
use serde_json::Value;

fn run(args: &[&str]) -> (bool, String, String) {
    let bin = env!("CARGO_BIN_EXE_constraint_dynamics");
    let out = std::process::Command::new(bin)
        .arg("envelope")
        .args(args)
        .current_dir(repo_dir())
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

fn kinds(limit: &Value) -> Vec<String> {
    let mut v: Vec<String> = limit["binding"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            format!(
                "{}:{}",
                b["kind"].as_str().unwrap(),
                b["name"].as_str().unwrap()
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn cli_envelope_prints_the_four_limits_and_what_binds_them() {
    let (ok, stdout, stderr) = run(&["--scene", "tests/data/cart_tall_mass.yaml"]);
    assert!(ok, "{stderr}");
    assert!(!stdout.contains("null"), "{stdout}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    for key in [
        "forward_acceleration",
        "forward_deceleration",
        "yaw_acceleration_left",
        "yaw_acceleration_right",
    ] {
        assert!(v[key]["max"].is_f64(), "{key}: {stdout}");
        assert!(v[key]["binding"].is_array(), "{key}: {stdout}");
    }
    // The closed forms of tests/it/envelope.rs: 2 τ_max / (r m_eff) and g |Σmx| / K.
    let a = v["forward_acceleration"]["max"].as_f64().unwrap();
    assert!((a - 8.0 / 3.35).abs() < 1e-6 * a, "{a}");
    assert_eq!(
        kinds(&v["forward_acceleration"]),
        ["effort:left_wheel_joint", "effort:right_wheel_joint"]
    );
    let d = v["forward_deceleration"]["max"].as_f64().unwrap();
    assert!((d - 9.81 * 2.7 / 13.325).abs() < 1e-6 * d, "{d}");
    assert_eq!(
        kinds(&v["forward_deceleration"]),
        ["lift_off:caster_contact"]
    );
    assert_eq!(v["unchecked"], serde_json::json!([]));

    // A state file: its tau is ignored (the same limits whatever it says).
    let file = std::env::temp_dir().join(format!("cd_envelope_{}.json", std::process::id()));
    std::fs::write(
        &file,
        r#"{"q": [0, 0, 0, 0, 0, 0, 1, 0, 0], "tau": [0, 0, 0, 0, 0, 0, 100, -100]}"#,
    )
    .unwrap();
    let (ok, stdout2, stderr) = run(&[
        "--scene",
        "tests/data/cart_tall_mass.yaml",
        "--state",
        file.to_str().unwrap(),
    ]);
    std::fs::remove_file(&file).ok();
    assert!(ok, "{stderr}");
    let v2: Value = serde_json::from_str(&stdout2).unwrap();
    assert_eq!(v2["forward_acceleration"], v["forward_acceleration"]);
}

#[test]
fn cli_envelope_lists_what_it_cannot_check_and_refuses_a_fixed_base() {
    // Planar base: no normal rows, no friction given.
    let (ok, stdout, stderr) = run(&["--scene", "params/diff_drive.yaml"]);
    assert!(ok, "{stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    let unchecked: Vec<String> = v["unchecked"]
        .as_array()
        .unwrap()
        .iter()
        .map(|u| {
            format!(
                "{}:{}",
                u["kind"].as_str().unwrap(),
                u["name"].as_str().unwrap()
            )
        })
        .collect();
    assert!(
        unchecked.contains(&"lift_off:left_wheel_contact".to_string()),
        "{stdout}"
    );
    assert!(
        unchecked.contains(&"friction:right_wheel_contact".to_string()),
        "{stdout}"
    );
    let (ok, _, stderr) = run(&["--scene", "params/fourbar.yaml"]);
    assert!(!ok && stderr.contains("fixed-base"), "{stderr}");
}

#[test]
fn cli_envelope_reflects_the_scenes_payload() {
    // tests/data/cart_tall_mass_payload.yaml: the cart with 5 kg at x = −0.1 m, z = 1.0 m above
    // the ground. The closed forms of tests/it/payload.rs with the payload's mass added:
    // 2 τ_max / (r (M + m_p + 2 I_w/r²)) = 8 / 3.85 and g |Σmx + m_p x_p| / (Σmz + m_p z_p + 2 I_w/r)
    // = 9.81 × 3.2 / 18.325 (without it 8 / 3.35 and 9.81 × 2.7 / 13.325).
    let (ok, stdout, stderr) = run(&["--scene", "tests/data/cart_tall_mass_payload.yaml"]);
    assert!(ok, "{stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    let a = v["forward_acceleration"]["max"].as_f64().unwrap();
    assert!((a - 8.0 / 3.85).abs() < 1e-8 * a, "{a}");
    let d = v["forward_deceleration"]["max"].as_f64().unwrap();
    assert!((d - 9.81 * 3.2 / 18.325).abs() < 1e-8 * d, "{d}");
    assert_eq!(
        kinds(&v["forward_deceleration"]),
        ["lift_off:caster_contact"]
    );
}
