//! The `project` subcommand end to end (the binary, JSON on stdout, a request file, bad input).

#[path = "../../tests/common/mod.rs"]
mod common;

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
