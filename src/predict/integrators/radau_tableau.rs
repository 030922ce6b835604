//! The Radau IIA tableau of order 5 (Hairer & Wanner II, IV.5, Table 5.6) and what RADAU5 derives
//! from it: the eigen-decomposition of A⁻¹ that splits the Newton system, and the weights of the
//! embedded error estimate (IV.8). Checked against the order conditions in the tests below.

use nalgebra::{Matrix3, Vector3};

/// The Butcher matrix A of Radau IIA, s = 3 (b = its last row).
pub fn butcher_a() -> [[f64; 3]; 3] {
    let s6 = 6f64.sqrt();
    [
        [
            (88.0 - 7.0 * s6) / 360.0,
            (296.0 - 169.0 * s6) / 1800.0,
            (-2.0 + 3.0 * s6) / 225.0,
        ],
        [
            (296.0 + 169.0 * s6) / 1800.0,
            (88.0 + 7.0 * s6) / 360.0,
            (-2.0 - 3.0 * s6) / 225.0,
        ],
        [(16.0 - s6) / 36.0, (16.0 + s6) / 36.0, 1.0 / 9.0],
    ]
}

/// The Radau IIA (s = 3) coefficients and the transformation of A⁻¹.
#[derive(Clone, Debug)]
pub struct RadauCoefficients {
    /// Nodes c = ((4 − √6)/10, (4 + √6)/10, 1).
    pub c: [f64; 3],
    /// Error-estimate weights: err = (γ/h − J)⁻¹ (f₀ + Σ d_i Z_i / h).
    pub d: [f64; 3],
    /// Eigenvalues of A⁻¹: γ (real) and α ± iβ.
    pub gamma: f64,
    pub alpha: f64,
    pub beta: f64,
    /// A⁻¹ = T Λ T⁻¹ with Λ = [[γ, 0, 0], [0, α, β], [0, −β, α]].
    pub t: Matrix3<f64>,
    pub t_inv: Matrix3<f64>,
}

impl RadauCoefficients {
    pub fn new() -> Self {
        let s6 = 6f64.sqrt();
        let a = butcher_a();
        let c = [(4.0 - s6) / 10.0, (4.0 + s6) / 10.0, 1.0];
        let d = [
            -(13.0 + 7.0 * s6) / 3.0,
            (-13.0 + 7.0 * s6) / 3.0,
            -1.0 / 3.0,
        ];
        // The eigenvalues of A⁻¹ in closed form (RADAU5's u1, alph, beta).
        let (c81, c9) = (81f64.cbrt(), 9f64.cbrt());
        let u1 = (6.0 + c81 - c9) / 30.0;
        let (al, be) = ((12.0 - c81 + c9) / 60.0, (c81 + c9) * 3f64.sqrt() / 60.0);
        let cno = al * al + be * be;
        let (gamma, alpha, beta) = (1.0 / u1, al / cno, be / cno);
        let a_inv = Matrix3::from_fn(|i, j| a[i][j])
            .try_inverse()
            .expect("Radau IIA's A is invertible");
        // Eigenvectors: a null vector of the (rank-2) A⁻¹ − λI is the cross product of two of
        // its rows, also for complex λ (the bilinear cross product is orthogonal to both rows).
        let real = {
            let m = a_inv - Matrix3::identity() * gamma;
            Vector3::from(m.row(0).transpose().cross(&m.row(1).transpose()))
        };
        let (re, im) = {
            // Rows of A⁻¹ − (α + iβ)I as (real, imaginary) parts.
            let row = |i: usize| {
                let mut r = a_inv.row(i).transpose();
                r[i] -= alpha;
                let mut m = Vector3::zeros();
                m[i] = -beta;
                (r, m)
            };
            let ((ar, ai), (br, bi)) = (row(0), row(1));
            // (ar + i ai) × (br + i bi)
            (ar.cross(&br) - ai.cross(&bi), ar.cross(&bi) + ai.cross(&br))
        };
        let t = Matrix3::from_columns(&[real, re, im]);
        let t_inv = t.try_inverse().expect("A⁻¹'s eigenvectors are independent");
        Self {
            c,
            d,
            gamma,
            alpha,
            beta,
            t,
            t_inv,
        }
    }
}

impl Default for RadauCoefficients {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The collocation conditions C(3): Σ_j a_ij c_j^(k−1) = c_i^k / k (k = 1, 2, 3), B(5):
    /// Σ_i b_i c_i^(k−1) = 1/k (k = 1 … 5, b = A's last row: order 5), and the estimate's weights
    /// vanish on polynomials of degree ≤ 2 (order 3): Σ d_i c_i = −1, Σ d_i c_i² = Σ d_i c_i³ = 0.
    #[test]
    fn tableau_meets_its_order_conditions() {
        let (co, a) = (RadauCoefficients::new(), butcher_a());
        for i in 0..3 {
            for k in 1..=3 {
                let lhs: f64 = (0..3).map(|j| a[i][j] * co.c[j].powi(k - 1)).sum();
                assert!(
                    (lhs - co.c[i].powi(k) / k as f64).abs() < 1e-15,
                    "C(3) {i} {k}"
                );
            }
        }
        for k in 1..=5 {
            let lhs: f64 = (0..3).map(|i| a[2][i] * co.c[i].powi(k - 1)).sum();
            assert!((lhs - 1.0 / k as f64).abs() < 1e-15, "B(5) {k}");
        }
        let d = |k: i32| -> f64 { (0..3).map(|i| co.d[i] * co.c[i].powi(k)).sum() };
        assert!((d(1) + 1.0).abs() < 1e-14 && d(2).abs() < 1e-14 && d(3).abs() < 1e-14);
    }

    /// T⁻¹ A⁻¹ T = [[γ, 0, 0], [0, α, β], [0, −β, α]], with RADAU5's closed-form eigenvalues
    /// (γ = 3.6378, α ± iβ = 2.6811 ± 3.0504i).
    #[test]
    fn transformation_block_diagonalises_the_inverse_tableau() {
        let (co, a) = (RadauCoefficients::new(), butcher_a());
        let a_inv = Matrix3::from_fn(|i, j| a[i][j]).try_inverse().unwrap();
        let l = co.t_inv * a_inv * co.t;
        let expect = Matrix3::new(
            co.gamma, 0.0, 0.0, 0.0, co.alpha, co.beta, 0.0, -co.beta, co.alpha,
        );
        assert!((l - expect).amax() < 1e-13, "{l}");
        assert!((co.gamma - 3.637834252744496).abs() < 1e-14);
        assert!((co.alpha - 2.681082873627752).abs() < 1e-14);
        assert!((co.beta - 3.050430199247411).abs() < 1e-14);
        // The trace and determinant of A⁻¹ are those of Λ.
        assert!((a_inv.trace() - (co.gamma + 2.0 * co.alpha)).abs() < 1e-13);
        let det = co.gamma * (co.alpha * co.alpha + co.beta * co.beta);
        assert!((a_inv.determinant() - det).abs() < 1e-12);
    }
}
