//! The minimum-norm solution λ = S⁺ r of a singular Gram system S λ = r (S = YᵀY, n × n, positive
//! semi-definite), on a preallocated workspace: the multipliers of redundant or singular
//! constraint sets.
//!
//! A Cholesky factorization with diagonal pivoting, `P S Pᵀ = [L₁₁; L₂₁][L₁₁ᵀ L₂₁ᵀ]`, takes at
//! each step the largest remaining pivot — the column of Y farthest from the span of those taken
//! (column-pivoted QR of Y, done on S) — and stops when it is ≤ `tol` · max diag(S): that gives a
//! maximal independent set I (k columns) and the dependent rest D, Y_D = Y_I C with
//! C = S_II⁻¹ S_ID = L₁₁⁻ᵀ L₂₁ᵀ. So Y = Y_I E with E = [I C] (columns in (I, D) order) of full row
//! rank, S = Eᵀ S_II E and
//!   S⁺ = Eᵀ G⁻¹ S_II⁻¹ G⁻¹ E,  G = E Eᵀ = I + C Cᵀ,
//! (the pseudo-inverse of a full-column-rank times a full-row-rank product). The projection of r
//! on range(S) = range(Eᵀ) is r̂ = Eᵀ G⁻¹ E r; what is left, r − r̂, is the part of the right side
//! no λ can meet. S⁺ is unique, so λ is smooth in S whichever independent set was picked.

use super::dense::{cholesky_in_place, cholesky_solve, solve_lower_transpose};
use nalgebra::DMatrix;

/// Workspace of [`MinNormSolver::solve`] for n × n systems.
#[derive(Clone, Debug, Default)]
pub struct MinNormSolver {
    /// P S Pᵀ, then its pivoted factor (L₁₁ leading k × k, L₂₁ below).
    l: DMatrix<f64>,
    /// perm[i]: the row of S at pivoted position i (I = perm[..k], D = perm[k..]).
    perm: Vec<usize>,
    /// C (leading k × (n − k)) and the factor of G (k × k).
    c: DMatrix<f64>,
    g: DMatrix<f64>,
    w: Vec<f64>,
    /// r̂: the projection of the last right side on range(S) (n).
    pub r_hat: Vec<f64>,
}

impl MinNormSolver {
    /// Workspace for n × n systems.
    pub fn new(n: usize) -> Self {
        Self {
            l: DMatrix::zeros(n, n),
            perm: Vec::with_capacity(n),
            c: DMatrix::zeros(n, n),
            g: DMatrix::zeros(n, n),
            w: vec![0.0; n],
            r_hat: vec![0.0; n],
        }
    }

    /// λ = S⁺ r for the symmetric positive semi-definite S (both triangles), the pivots above
    /// `tol` · max diag(S) counting as independent (`tol` is a squared sine: the squared
    /// relative QR pivot of Y). Writes λ and [`MinNormSolver::r_hat`]; returns the rank k.
    pub fn solve(&mut self, s: &DMatrix<f64>, r: &[f64], tol: f64, lambda: &mut [f64]) -> usize {
        let n = s.nrows();
        if self.l.nrows() != n {
            *self = Self::new(n);
        }
        let k = self.pivoted_cholesky(s, tol);
        lambda.iter_mut().for_each(|x| *x = 0.0);
        self.r_hat.iter_mut().for_each(|x| *x = 0.0);
        if k == 0 {
            return 0;
        }
        let nd = n - k;
        // C = L₁₁⁻ᵀ L₂₁ᵀ, column by column.
        for b in 0..nd {
            let mut col = self.c.column_mut(b);
            let col = &mut col.as_mut_slice()[..k];
            for (a, x) in col.iter_mut().enumerate() {
                *x = self.l[(k + b, a)];
            }
            solve_lower_transpose(&self.l, k, col);
        }
        // G = I + C Cᵀ (positive definite whatever C is).
        for a in 0..k {
            for b in 0..=a {
                let cc: f64 = (0..nd).map(|e| self.c[(a, e)] * self.c[(b, e)]).sum();
                let v = cc + if a == b { 1.0 } else { 0.0 };
                self.g[(a, b)] = v;
                self.g[(b, a)] = v;
            }
        }
        let g_ok = cholesky_in_place(&mut self.g, k, 0.0);
        debug_assert!(g_ok.is_ok(), "I + C Cᵀ is positive definite");
        // w = G⁻¹ E r;  r̂ = Eᵀ w.
        let (ind, dep) = self.perm.split_at(k);
        let w = &mut self.w[..k];
        for (a, &i) in ind.iter().enumerate() {
            w[a] = r[i] + (0..nd).map(|e| self.c[(a, e)] * r[dep[e]]).sum::<f64>();
        }
        cholesky_solve(&self.g, k, w);
        scatter(ind, dep, &self.c, w, &mut self.r_hat);
        // λ = Eᵀ G⁻¹ S_II⁻¹ w.
        cholesky_solve(&self.l, k, w);
        cholesky_solve(&self.g, k, w);
        scatter(ind, dep, &self.c, w, lambda);
        k
    }

    /// `P S Pᵀ = L Lᵀ` with the largest remaining pivot first, into `l` and `perm`, stopping at
    /// the first pivot ≤ `tol` · max diag(S). Returns the rank.
    fn pivoted_cholesky(&mut self, s: &DMatrix<f64>, tol: f64) -> usize {
        let n = s.nrows();
        let l = &mut self.l;
        l.copy_from(s);
        self.perm.clear();
        self.perm.extend(0..n);
        let dmax = (0..n).map(|i| s[(i, i)]).fold(0.0, f64::max);
        for j in 0..n {
            let p = (j..n).fold(j, |p, i| if l[(i, i)] > l[(p, p)] { i } else { p });
            let pivot = l[(p, p)];
            if pivot.is_nan() || pivot <= tol * dmax {
                return j;
            }
            if p != j {
                l.swap_rows(p, j);
                l.swap_columns(p, j);
                self.perm.swap(p, j);
            }
            let d = l[(j, j)].sqrt();
            l[(j, j)] = d;
            for i in j + 1..n {
                l[(i, j)] /= d;
            }
            // Trailing block, both triangles (the row and column swaps read either).
            for c in j + 1..n {
                for i in c..n {
                    let v = l[(i, c)] - l[(i, j)] * l[(c, j)];
                    l[(i, c)] = v;
                    l[(c, i)] = v;
                }
            }
        }
        n
    }
}

/// `out = Eᵀ w`: out_I = w, out_D = Cᵀ w.
fn scatter(ind: &[usize], dep: &[usize], c: &DMatrix<f64>, w: &[f64], out: &mut [f64]) {
    for (a, &i) in ind.iter().enumerate() {
        out[i] = w[a];
    }
    for (e, &d) in dep.iter().enumerate() {
        out[d] = (0..ind.len()).map(|a| c[(a, e)] * w[a]).sum();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the SVD pseudo-inverse: two identical columns and a zero one (the diff drive's
    /// lateral and normal rows), a right side partly outside range(S).
    #[test]
    fn equals_the_svd_pseudo_inverse() {
        let y = DMatrix::from_row_slice(
            3,
            4,
            &[1.0, 1.0, 0.0, 0.5, 0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 0.0, -1.0],
        );
        let s = y.transpose() * &y;
        let r = [1.0, -0.5, 0.3, 2.0];
        let mut solver = MinNormSolver::new(4);
        let mut lambda = [0.0; 4];
        let rank = solver.solve(&s, &r, 1e-12, &mut lambda);
        assert_eq!(rank, 2);
        let pinv = s.clone().pseudo_inverse(1e-12).unwrap();
        let rv = nalgebra::DVector::from_column_slice(&r);
        let expected = &pinv * &rv;
        let r_hat = &s * &expected;
        for i in 0..4 {
            assert!(
                (lambda[i] - expected[i]).abs() < 1e-14,
                "{lambda:?} {expected}"
            );
            assert!((solver.r_hat[i] - r_hat[i]).abs() < 1e-14);
        }
    }
}
