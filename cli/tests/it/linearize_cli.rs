//! `constraint_dynamics linearize` end to end, against closed forms: the A01 pendulum (1 kg point
//! mass, L = 1 m, q̈ = g cos q, M = 1 kg·m²) at its lowest point q = π/2, at rest, where the
//! linearized dynamics are ẋ = L x + b u with L = [0 1; −g 0], b = (0, 1). There every stage
//! of a step sits at the equilibrium, so the step's linearization is the method's polynomial
//! of h L: RK4 A = Σ_{k≤4} (hL)^k/k!, B = h Σ_{k≤3} (hL)^k/(k+1)! b; semi-implicit Euler
//! A = [1 − h²g, h; −h g, 1], B = (h², h).

use crate::common;
use common::*;
use nalgebra::{Matrix2, Vector2};
use std::process::Command;

const G: f64 = 9.81;
const H: f64 = 0.01;

fn linearize(method: &str) -> serde_json::Value {
    let dir = std::env::temp_dir().join(format!("cd_lin_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let state = dir.join("bottom.json");
    std::fs::write(
        &state,
        serde_json::json!({"q": [std::f64::consts::FRAC_PI_2], "v": [0.0]}).to_string(),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_constraint_dynamics"))
        .current_dir(repo_dir())
        .args(["linearize", "--scene", "params/pendulum_a01.yaml", "--dt"])
        .arg(H.to_string())
        .args(["--method", method, "--state"])
        .arg(&state)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "linearize failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn flat(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().unwrap().iter().flat_map(vecf).collect()
}

#[test]
fn linearize_prints_the_closed_form_step_matrices_of_the_pendulum() {
    let l = Matrix2::new(0.0, 1.0, -G, 0.0) * H;
    let b = Vector2::new(0.0, 1.0);
    let (mut a_rk4, mut b_rk4, mut p) = (Matrix2::zeros(), Vector2::zeros(), Matrix2::identity());
    let mut fact = 1.0;
    for k in 0..=4 {
        if k > 0 {
            p *= l;
            fact *= k as f64;
        }
        a_rk4 += p / fact;
        if k <= 3 {
            b_rk4 += p * b * (H / (fact * (k as f64 + 1.0)));
        }
    }
    let out = linearize("rk4");
    let row_major = |m: &Matrix2<f64>| vec![m[(0, 0)], m[(0, 1)], m[(1, 0)], m[(1, 1)]];
    // Achieved 1.4e-17 and 1.7e-18 (SIE: exactly 0): rounding (g cos q at q = π/2 is 6e-16).
    assert_close("rk4 A", &flat(&out["A"]), &row_major(&a_rk4), 1e-14);
    assert_close("rk4 B", &flat(&out["B"]), &[b_rk4[0], b_rk4[1]], 1e-14);

    let out = linearize("semi_implicit_euler");
    let a_sie = [1.0 - H * H * G, H, -H * G, 1.0];
    assert_close("sie A", &flat(&out["A"]), &a_sie, 1e-14);
    assert_close("sie B", &flat(&out["B"]), &[H * H, H], 1e-14);
}
