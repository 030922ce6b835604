//! Closed-form references of the report, from the formulas (nothing of the crate's dynamics):
//! Jacobi's sn, cn, dn and K by the arithmetic-geometric mean; the A01 pendulum; the
//! parallelogram mode of the double four-bar; the modal solution of a linear chain.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use std::f64::consts::PI;

const G: f64 = 9.81;

/// K(k) = π / (2 AGM(1, √(1 − k²))).
pub fn elliptic_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    // Quadratic convergence: a few iterations; the cap guards against a last-bit oscillation.
    for _ in 0..40 {
        if (a - b).abs() <= 2.0 * f64::EPSILON * a {
            break;
        }
        (a, b) = (0.5 * (a + b), (a * b).sqrt());
    }
    PI / (2.0 * a)
}

/// (sn, cn, dn)(u; k) by the descending AGM (Abramowitz & Stegun 16.4): aₙ₊₁ = (aₙ + bₙ)/2,
/// bₙ₊₁ = √(aₙbₙ), cₙ₊₁ = (aₙ − bₙ)/2; φ_N = 2^N a_N u, φₙ₋₁ = (φₙ + asin(cₙ sin φₙ / aₙ))/2.
pub fn sn_cn_dn(u: f64, k: f64) -> (f64, f64, f64) {
    let period = 4.0 * elliptic_k(k);
    let u = u - period * (u / period).round();
    let mut a = [0.0f64; 40];
    let mut c = [0.0f64; 40];
    let (mut an, mut bn) = (1.0f64, (1.0 - k * k).sqrt());
    a[0] = an;
    c[0] = k;
    let mut n = 0;
    while n + 1 < a.len() && c[n].abs() > 2.0 * f64::EPSILON * a[n] {
        n += 1;
        c[n] = 0.5 * (an - bn);
        (an, bn) = (0.5 * (an + bn), (an * bn).sqrt());
        a[n] = an;
    }
    let mut phi = 2f64.powi(n as i32) * a[n] * u;
    for i in (1..=n).rev() {
        phi = 0.5 * (phi + (c[i] / a[i] * phi.sin()).asin());
    }
    let (sn, cn) = phi.sin_cos();
    (sn, cn, (1.0 - k * k * sn * sn).sqrt())
}

/// A01: mass position (x, z) at t; sin(θ/2) = k sn(K − ω₀t; k), k = sin(θ₀/2), θ₀ = π/2 from the
/// downward vertical, ω₀ = √(g/L), L = 1 m.
pub fn a01_position(t: f64) -> (f64, f64) {
    let k = (PI / 4.0).sin();
    let (sn, _, _) = sn_cn_dn(elliptic_k(k) - G.sqrt() * t, k);
    let theta = 2.0 * (k * sn).asin();
    (theta.sin(), -theta.cos())
}

/// Double four-bar, parallelogram mode: every crank angle θ obeys 3θ̈ = −3.5 g cos θ from
/// θ₀ = π/2, θ̇₀ = −1 (a circulating pendulum in φ = θ + π/2): ψ = φ/2 = am(K − wt; k),
/// w = √((E + c)/2), c = 3.5g/3, E = ½ + c, k² = 2c/(E + c); cos θ = 2 sn cn, sin θ = 2 sn² − 1.
pub fn parallelogram_angle(t: f64) -> f64 {
    let c = 3.5 * G / 3.0;
    let e = 0.5 + c;
    let k = (2.0 * c / (e + c)).sqrt();
    let (sn, cn, _) = sn_cn_dn(elliptic_k(k) - ((e + c) / 2.0).sqrt() * t, k);
    (2.0 * sn * sn - 1.0).atan2(2.0 * sn * cn)
}

/// Angle difference wrapped to (−π, π].
pub fn wrap(a: f64) -> f64 {
    a.sin().atan2(a.cos())
}

/// Linear chain M q̈ + K q = 0 from (q₀, 0): q(t) = L⁻ᵀ U cos(Ωt) Uᵀ Lᵀ q₀ with M = LLᵀ,
/// L⁻¹KL⁻ᵀ = UΩ²Uᵀ. Built once; `at(t)` evaluates.
pub struct Modes {
    back: DMatrix<f64>,
    omega: DVector<f64>,
    a: DVector<f64>,
}

impl Modes {
    pub fn new(m: &DMatrix<f64>, k: &DMatrix<f64>, q0: &[f64]) -> Self {
        let l = m.clone().cholesky().expect("M > 0").l();
        let linv = l.clone().try_inverse().expect("L invertible");
        let a = &linv * k * linv.transpose();
        let eig = SymmetricEigen::new(0.5 * (&a + a.transpose()));
        let u = eig.eigenvectors;
        Self {
            a: u.transpose() * l.transpose() * DVector::from_column_slice(q0),
            omega: eig.eigenvalues.map(|x| x.max(0.0).sqrt()),
            back: linv.transpose() * u,
        }
    }

    pub fn at(&self, t: f64) -> Vec<f64> {
        let z = DVector::from_fn(self.a.len(), |i, _| (self.omega[i] * t).cos() * self.a[i]);
        (&self.back * z).iter().copied().collect()
    }
}

/// Relative-coordinate mass matrix of sliders in series: M_jk = Σ_{i ≥ max(j,k)} m_i.
pub fn chain_mass(masses: &[f64]) -> DMatrix<f64> {
    let n = masses.len();
    DMatrix::from_fn(n, n, |j, k| masses[j.max(k)..].iter().sum())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agm_functions_match_known_values() {
        assert!((elliptic_k((0.5f64).sqrt()) - 1.854074677301372).abs() < 1e-14);
        let (sn, cn, dn) = sn_cn_dn(0.7, 0.6);
        assert!((sn * sn + cn * cn - 1.0).abs() < 1e-15 && dn > 0.0);
        assert!((sn_cn_dn(0.3, 0.0).0 - 0.3f64.sin()).abs() < 1e-15);
        let (x, z) = a01_position(0.0);
        assert!((x - 1.0).abs() < 1e-15 && z.abs() < 1e-7);
        assert!((parallelogram_angle(0.0) - PI / 2.0).abs() < 1e-7);
    }
}
