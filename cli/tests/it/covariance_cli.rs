//! `constraint_dynamics predict --covariance`: the propagated covariance in every sample,
//! against the closed form of the spring-chain scene with nothing acting along its sliders
//! (params/spring_chain.yaml: five prismatic joints along x, gravity −z): q̈ = 0, so
//! q(t) = q₀ + v₀ t, Φ(t) = [1 t; 0 1] per slider and P(t) = Φ P₀ Φᵀ:
//! var q = σ_q² + t² σ_v², cov(q, v) = t σ_v², var v = σ_v².

use crate::common;
use common::*;
use std::process::Command;

#[test]
fn predict_carries_the_closed_form_covariance_of_free_sliders() {
    let dir = std::env::temp_dir().join(format!("cd_cov_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (sq, sv) = ([0.01, 0.0, 0.02, 0.005, 0.0], [0.02, 0.03, 0.0, 0.01, 0.04]);
    let names = ["slider1", "slider2", "slider3", "slider4", "slider5"];
    let mut sigma = serde_json::Map::new();
    for (k, n) in names.iter().enumerate() {
        sigma.insert(n.to_string(), sq[k].into());
        sigma.insert(format!("{n}:rate"), sv[k].into());
    }
    let cov = dir.join("sigma.json");
    std::fs::write(&cov, serde_json::json!({ "sigma": sigma }).to_string()).unwrap();
    let state = dir.join("state.json");
    std::fs::write(
        &state,
        serde_json::json!({"q": [0.0, 0.1, 0.0, -0.1, 0.0], "v": [0.1, -0.2, 0.3, 0.0, 0.05]})
            .to_string(),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_constraint_dynamics"))
        .current_dir(repo_dir())
        .args([
            "predict",
            "--scene",
            "params/spring_chain.yaml",
            "--horizon",
            "1.0",
        ])
        .arg("--state")
        .arg(&state)
        .arg("--covariance")
        .arg(&cov)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "predict failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let samples = json["samples"].as_array().unwrap();
    assert!(samples.len() > 10);
    for s in samples {
        let t = s["t"].as_f64().unwrap();
        let p: Vec<Vec<f64>> = s["covariance"]
            .as_array()
            .expect("covariance in every sample")
            .iter()
            .map(vecf)
            .collect();
        assert_eq!(p.len(), 10);
        let mut expected = vec![vec![0.0; 10]; 10];
        for k in 0..5 {
            let (q2, v2) = (sq[k] * sq[k], sv[k] * sv[k]);
            expected[k][k] = q2 + t * t * v2;
            expected[k][5 + k] = t * v2;
            expected[5 + k][k] = t * v2;
            expected[5 + k][5 + k] = v2;
        }
        let ours: Vec<f64> = p.concat();
        // Achieved ≤ 2.1e-17 (relative to max(1, max entry)): rounding.
        assert_close(&format!("P(t = {t})"), &ours, &expected.concat(), 1e-15);
    }
}
