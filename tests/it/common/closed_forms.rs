//! Closed-form solutions the propagation tests compare against, written here from the formulas (no
//! code of the crate): Jacobi's elliptic functions by the arithmetic-geometric mean, the IFToMM A01
//! pendulum, the parallelogram mode of the double four-bar (a circulating pendulum) and the modal
//! solution of a linear spring chain. The propagation test files include it with
//! `#[path = "common/closed_forms.rs"] mod closed_forms;`; tests/it/propagation_closed_forms.rs
//! checks the functions themselves.
#![allow(dead_code)]

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use std::f64::consts::PI;

/// Standard gravity used by the bundled scenes [m/s²].
pub const G: f64 = 9.81;

/// Complete elliptic integral of the first kind K(k) = π / (2 AGM(1, √(1 − k²))).
pub fn elliptic_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    for _ in 0..64 {
        if (a - b).abs() <= 1e-16 * a {
            break;
        }
        (a, b) = (0.5 * (a + b), (a * b).sqrt());
    }
    PI / (2.0 * a)
}

/// Jacobi (sn, cn, dn)(u; k) by the descending Landen / AGM scheme (Abramowitz & Stegun 16.4):
/// a₀ = 1, b₀ = k', c₀ = k; aₙ₊₁ = (aₙ + bₙ)/2, bₙ₊₁ = √(aₙbₙ), cₙ₊₁ = (aₙ − bₙ)/2 until c_N ≈ 0;
/// φ_N = 2^N a_N u, φₙ₋₁ = (φₙ + asin(cₙ/aₙ sin φₙ))/2; sn = sin φ₀, cn = cos φ₀,
/// dn = √(1 − k² sn²). The argument is first reduced modulo the period 4K.
pub fn jacobi_sn_cn_dn(u: f64, k: f64) -> (f64, f64, f64) {
    let big_k = elliptic_k(k);
    let u = u - 4.0 * big_k * (u / (4.0 * big_k)).round();
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    let mut a_s = vec![a];
    let mut c_s = vec![k];
    for _ in 0..64 {
        let c = 0.5 * (a - b);
        (a, b) = (0.5 * (a + b), (a * b).sqrt());
        a_s.push(a);
        c_s.push(c);
        if c.abs() <= 1e-17 {
            break;
        }
    }
    let n = a_s.len() - 1;
    let mut phi = 2f64.powi(n as i32) * a_s[n] * u;
    for i in (1..=n).rev() {
        phi = 0.5 * (phi + (c_s[i] / a_s[i] * phi.sin()).asin());
    }
    let (sn, cn) = phi.sin_cos();
    // dn > 0 for k < 1; the square root is well conditioned where cn/cos(φ₁ − φ₀) is not (cn ≈ 0)
    (sn, cn, (1.0 - k * k * sn * sn).sqrt())
}

/// A01 pendulum (point mass on a massless link of length `l`, released at rest from the horizontal;
/// the scene's angle q is measured from the horizontal, so θ = π/2 − q from the downward vertical):
/// sin(θ/2) = k sn(K(k) − ω₀ t; k), k = sin(θ₀/2), ω₀ = √(g/L). Returns the mass position (x, z).
pub fn a01_position(t: f64, l: f64) -> (f64, f64) {
    let theta0 = PI / 2.0;
    let k = (theta0 / 2.0).sin();
    let w0 = (G / l).sqrt();
    let (sn, _, _) = jacobi_sn_cn_dn(elliptic_k(k) - w0 * t, k);
    let theta = 2.0 * (k * sn).asin();
    (l * theta.sin(), -l * theta.cos())
}

/// A01 angle q (from the horizontal, as in `params/pendulum_a01.yaml`) and rate.
pub fn a01_state(t: f64) -> (f64, f64) {
    let k = (PI / 4.0).sin();
    let w0 = G.sqrt();
    let (sn, cn, dn) = jacobi_sn_cn_dn(elliptic_k(k) - w0 * t, k);
    let s = k * sn;
    let theta = 2.0 * s.asin();
    // θ̇ = 2 k cn dn (−ω₀) / cos(θ/2)
    let theta_dot = -2.0 * k * cn * dn * w0 / (1.0 - s * s).sqrt();
    (PI / 2.0 - theta, -theta_dot)
}

/// Parallelogram mode of the double four-bar (`params/double_fourbar.yaml`): every crank angle θ
/// obeys 3 θ̈ = −3.5 g cos θ from θ₀ = π/2, θ̇₀ = −1. With φ = θ + π/2 it is a pendulum
/// φ̈ = −c sin φ, c = 3.5 g / 3, here circulating: ψ = φ/2 = am(K − w t; k) with
/// w = √((E + c)/2), E = ½θ̇₀² + c, k² = 2c/(E + c); cos θ = 2 sn cn, sin θ = 2 sn² − 1.
/// Returns (cos θ, sin θ, θ̇).
pub fn parallelogram_crank(t: f64) -> (f64, f64, f64) {
    let c = 3.5 * G / 3.0;
    let e = 0.5 + c;
    let w = ((e + c) / 2.0).sqrt();
    let k = (2.0 * c / (e + c)).sqrt();
    let (sn, cn, dn) = jacobi_sn_cn_dn(elliptic_k(k) - w * t, k);
    // ψ̇ = −w dn, θ̇ = φ̇ = 2ψ̇
    (2.0 * sn * cn, 2.0 * sn * sn - 1.0, -2.0 * w * dn)
}

/// Linear chain M q̈ + K q = 0 solved by its modes: with M = LLᵀ and L⁻¹ K L⁻ᵀ = U Ω² Uᵀ,
/// q(t) = L⁻ᵀ U [cos(ωt) a + sin(ωt)/ω b], a = Uᵀ Lᵀ q₀, b = Uᵀ Lᵀ v₀. Returns (q, v).
pub fn linear_modes(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    q0: &[f64],
    v0: &[f64],
    t: f64,
) -> (Vec<f64>, Vec<f64>) {
    let n = m.nrows();
    let l = m.clone().cholesky().expect("M > 0").l();
    let linv = l.clone().try_inverse().unwrap();
    let a_mat = &linv * k * linv.transpose();
    let eig = SymmetricEigen::new(0.5 * (&a_mat + a_mat.transpose()));
    let u = eig.eigenvectors;
    let a = u.transpose() * l.transpose() * DVector::from_column_slice(q0);
    let b = u.transpose() * l.transpose() * DVector::from_column_slice(v0);
    let mut zq = DVector::zeros(n);
    let mut zv = DVector::zeros(n);
    for i in 0..n {
        let w = eig.eigenvalues[i].max(0.0).sqrt();
        let (s, c) = (w * t).sin_cos();
        let sinc = if w * t == 0.0 { t } else { s / w };
        zq[i] = c * a[i] + sinc * b[i];
        zv[i] = -w * s * a[i] + c * b[i];
    }
    let back = linv.transpose() * u;
    (
        (&back * zq).iter().copied().collect(),
        (&back * zv).iter().copied().collect(),
    )
}

/// Mass matrix of n sliders in series on relative coordinates (q_i = x_i − x_{i−1}):
/// M_jk = Σ_{i ≥ max(j,k)} m_i.
pub fn relative_chain_mass(masses: &[f64]) -> DMatrix<f64> {
    let n = masses.len();
    DMatrix::from_fn(n, n, |j, k| masses[j.max(k)..].iter().sum())
}
