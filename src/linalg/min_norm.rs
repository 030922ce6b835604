//! The minimum-norm solution λ = S⁺ r of a singular Gram system S λ = r, S = YᵀY (n × n), on a
//! preallocated workspace: the multipliers of redundant or singular constraint sets.
//!
//! A column-pivoted QR of Y picks a maximal independent set I of its columns (k of them); the
//! others are combinations of those, Y_D = Y_I C with C = S_II⁻¹ S_ID (k × (n − k)). So
//! Y = Y_I E with E = [I C] (columns in (I, D) order) of full row rank, S = Eᵀ S_II E and
//!   S⁺ = Eᵀ G⁻¹ S_II⁻¹ G⁻¹ E,  G = E Eᵀ = I + C Cᵀ,
//! (the pseudo-inverse of a full-column-rank times a full-row-rank product). The projection of r
//! on range(S) = range(Eᵀ) is r̂ = Eᵀ G⁻¹ E r; what is left, r − r̂, is the part of the right side
//! no λ can meet. Everything is k × k work: smooth in S whichever independent set was picked,
//! since S⁺ is unique.

use super::dense::{cholesky_in_place, cholesky_solve};
use super::pivot::ColumnPivotedQr;
use nalgebra::DMatrix;

/// Workspace of [`MinNormSolver::solve`], sized for Y up to `rows` × n.
#[derive(Clone, Debug, Default)]
pub struct MinNormSolver {
    qr: ColumnPivotedQr,
    ind: Vec<usize>,
    dep: Vec<usize>,
    /// Cholesky factor of S_II (leading k × k), C (leading k × (n − k)), factor of G (k × k).
    l: DMatrix<f64>,
    c: DMatrix<f64>,
    g: DMatrix<f64>,
    w: Vec<f64>,
    /// r̂: the projection of the last right side on range(S) (n).
    pub r_hat: Vec<f64>,
}

impl MinNormSolver {
    /// Workspace for Y of `rows` × `n` (S and λ of size n).
    pub fn new(rows: usize, n: usize) -> Self {
        Self {
            qr: ColumnPivotedQr::new(rows, n),
            ind: Vec::with_capacity(n),
            dep: Vec::with_capacity(n),
            l: DMatrix::zeros(n, n),
            c: DMatrix::zeros(n, n),
            g: DMatrix::zeros(n, n),
            w: vec![0.0; n],
            r_hat: vec![0.0; n],
        }
    }

    /// λ = S⁺ r for S = YᵀY (both given; S with both triangles), the columns of Y independent
    /// while their QR pivot |r_kk| > `tol` · max |r_kk|. Writes λ and [`MinNormSolver::r_hat`];
    /// returns the rank k, or None when the independent block S_II does not factor (numerically
    /// singular despite the QR's decision).
    pub fn solve(
        &mut self,
        y: &DMatrix<f64>,
        s: &DMatrix<f64>,
        r: &[f64],
        tol: f64,
        lambda: &mut [f64],
    ) -> Option<usize> {
        let n = s.nrows();
        if self.l.nrows() < n || self.w.len() < n {
            *self = Self::new(y.nrows(), n);
        }
        self.qr
            .independent_columns(y.nrows(), n, |i, j| y[(i, j)], tol, &mut self.ind);
        let (ind, dep) = (&self.ind, &mut self.dep);
        dep.clear();
        dep.extend((0..n).filter(|j| !ind.contains(j)));
        let k = ind.len();
        lambda.iter_mut().for_each(|x| *x = 0.0);
        self.r_hat.iter_mut().for_each(|x| *x = 0.0);
        if k == 0 {
            return Some(0);
        }
        for (a, &i) in ind.iter().enumerate() {
            for (b, &j) in ind.iter().enumerate() {
                self.l[(a, b)] = s[(i, j)];
            }
        }
        cholesky_in_place(&mut self.l, k, 0.0).ok()?;
        // C = S_II⁻¹ S_ID, column by column.
        for (b, &d) in dep.iter().enumerate() {
            let mut col = self.c.column_mut(b);
            let col = &mut col.as_mut_slice()[..k];
            for (a, &i) in ind.iter().enumerate() {
                col[a] = s[(i, d)];
            }
            cholesky_solve(&self.l, k, col);
        }
        // G = I + C Cᵀ (positive definite whatever C is).
        let nd = dep.len();
        for a in 0..k {
            for b in 0..=a {
                let cc: f64 = (0..nd).map(|e| self.c[(a, e)] * self.c[(b, e)]).sum();
                let v = cc + if a == b { 1.0 } else { 0.0 };
                self.g[(a, b)] = v;
                self.g[(b, a)] = v;
            }
        }
        cholesky_in_place(&mut self.g, k, 0.0).ok()?;
        // w = G⁻¹ E r;  r̂ = Eᵀ w.
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
        Some(k)
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
        let mut solver = MinNormSolver::new(3, 4);
        let mut lambda = [0.0; 4];
        let rank = solver.solve(&y, &s, &r, 1e-6, &mut lambda).unwrap();
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
