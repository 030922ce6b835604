//! The minimum-norm solution λ = S⁺ r of a Gram system S λ = r (S = YᵀY, n × n, positive
//! semi-definite, possibly singular), on a preallocated workspace: the multipliers of every
//! constraint set, redundant and singular ones included.
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
//! no λ can meet. S⁺ is unique, so λ is smooth in S whichever independent set was picked. When
//! S has full rank (k = n) this is λ = S⁻¹ r through the pivoted factor, and r̂ = r.
//!
//! The matrices are a few rows wide (one per constraint row), so they live in flat column-major
//! buffers indexed directly: nalgebra's indexing and row swaps cost more than the arithmetic.

use nalgebra::DMatrix;

/// Workspace of [`MinNormSolver::solve`] for n × n systems.
#[derive(Clone, Debug, Default)]
pub struct MinNormSolver {
    n: usize,
    /// P S Pᵀ (both triangles), then its pivoted factor (L₁₁ leading k × k, L₂₁ below);
    /// column-major, leading dimension n.
    l: Vec<f64>,
    /// perm[i]: the row of S at pivoted position i (I = perm[..k], D = perm[k..]).
    perm: Vec<usize>,
    /// C (k × (n − k)) and the factor of G (k × k), column-major, leading dimension k.
    c: Vec<f64>,
    g: Vec<f64>,
    w: Vec<f64>,
    /// r̂: the projection of the last right side on range(S) (n).
    pub r_hat: Vec<f64>,
}

impl MinNormSolver {
    /// Workspace for n × n systems.
    pub fn new(n: usize) -> Self {
        Self {
            n,
            l: vec![0.0; n * n],
            perm: Vec::with_capacity(n),
            c: vec![0.0; n * n],
            g: vec![0.0; n * n],
            w: vec![0.0; n],
            r_hat: vec![0.0; n],
        }
    }

    /// λ = S⁺ r for the symmetric positive semi-definite S (its lower triangle is read), the
    /// pivots above `tol` · max diag(S) counting as independent (`tol` is a squared sine: the
    /// squared relative QR pivot of Y). Writes λ and [`MinNormSolver::r_hat`]; returns the rank k.
    pub fn solve(&mut self, s: &DMatrix<f64>, r: &[f64], tol: f64, lambda: &mut [f64]) -> usize {
        let n = s.nrows();
        if self.n != n {
            *self = Self::new(n);
        }
        let k = self.pivoted_cholesky(s, tol);
        let (ind, dep) = self.perm.split_at(k);
        let w = &mut self.w[..k];
        for (a, &i) in ind.iter().enumerate() {
            w[a] = r[i];
        }
        if k == n {
            // Full rank: λ = S⁻¹ r, and all of r is in range(S).
            self.r_hat.copy_from_slice(r);
            forward(&self.l, n, k, w);
            backward(&self.l, n, k, w);
            for (a, &i) in ind.iter().enumerate() {
                lambda[i] = w[a];
            }
            return k;
        }
        lambda.iter_mut().for_each(|x| *x = 0.0);
        self.r_hat.iter_mut().for_each(|x| *x = 0.0);
        if k == 0 {
            return 0;
        }
        let nd = n - k;
        let (l, c, g) = (&self.l, &mut self.c, &mut self.g);
        // C = L₁₁⁻ᵀ L₂₁ᵀ, column by column.
        for e in 0..nd {
            let col = &mut c[e * k..(e + 1) * k];
            for (a, x) in col.iter_mut().enumerate() {
                *x = l[a * n + k + e];
            }
            backward(l, n, k, col);
        }
        // G = I + C Cᵀ (positive definite whatever C is), factored in place.
        for b in 0..k {
            for a in b..k {
                let cc: f64 = (0..nd).map(|e| c[e * k + a] * c[e * k + b]).sum();
                g[b * k + a] = cc + if a == b { 1.0 } else { 0.0 };
            }
        }
        cholesky_lower(g, k);
        // w = G⁻¹ E r;  r̂ = Eᵀ w.
        for (a, wa) in w.iter_mut().enumerate() {
            *wa += (0..nd).map(|e| c[e * k + a] * r[dep[e]]).sum::<f64>();
        }
        forward(g, k, k, w);
        backward(g, k, k, w);
        scatter(ind, dep, c, w, &mut self.r_hat);
        // λ = Eᵀ G⁻¹ S_II⁻¹ w.
        forward(l, n, k, w);
        backward(l, n, k, w);
        forward(g, k, k, w);
        backward(g, k, k, w);
        scatter(ind, dep, c, w, lambda);
        k
    }

    /// `P S Pᵀ = L Lᵀ` with the largest remaining pivot first, into `l` and `perm`, stopping at
    /// the first pivot ≤ `tol` · max diag(S). Returns the rank.
    fn pivoted_cholesky(&mut self, s: &DMatrix<f64>, tol: f64) -> usize {
        let n = self.n;
        let l = &mut self.l;
        for b in 0..n {
            for a in b..n {
                let x = s[(a, b)];
                l[b * n + a] = x;
                l[a * n + b] = x;
            }
        }
        self.perm.clear();
        self.perm.extend(0..n);
        let dmax = (0..n).map(|i| l[i * n + i]).fold(0.0, f64::max);
        for j in 0..n {
            let p = (j..n).fold(j, |p, i| if l[i * n + i] > l[p * n + p] { i } else { p });
            let pivot = l[p * n + p];
            if pivot.is_nan() || pivot <= tol * dmax {
                return j;
            }
            if p != j {
                for col in 0..n {
                    l.swap(col * n + p, col * n + j);
                }
                for row in 0..n {
                    l.swap(p * n + row, j * n + row);
                }
                self.perm.swap(p, j);
            }
            let d = pivot.sqrt();
            l[j * n + j] = d;
            for i in j + 1..n {
                l[j * n + i] /= d;
            }
            // Trailing block, both triangles (the row and column swaps read either).
            for col in j + 1..n {
                let f = l[j * n + col];
                for i in col..n {
                    let v = l[col * n + i] - l[j * n + i] * f;
                    l[col * n + i] = v;
                    l[i * n + col] = v;
                }
            }
        }
        n
    }
}

/// Solve `L x = b` in place, L the leading k × k lower triangle of the column-major `l`
/// (leading dimension `ld`).
fn forward(l: &[f64], ld: usize, k: usize, x: &mut [f64]) {
    for i in 0..k {
        let mut s = x[i];
        for m in 0..i {
            s -= l[m * ld + i] * x[m];
        }
        x[i] = s / l[i * ld + i];
    }
}

/// Solve `Lᵀ x = b` in place (as [`forward`]).
fn backward(l: &[f64], ld: usize, k: usize, x: &mut [f64]) {
    for i in (0..k).rev() {
        let mut s = x[i];
        for m in i + 1..k {
            s -= l[i * ld + m] * x[m];
        }
        x[i] = s / l[i * ld + i];
    }
}

/// In-place Cholesky of a positive-definite k × k lower triangle (leading dimension k).
fn cholesky_lower(g: &mut [f64], k: usize) {
    for j in 0..k {
        for m in 0..j {
            let f = g[m * k + j];
            for i in j..k {
                g[j * k + i] -= g[m * k + i] * f;
            }
        }
        let d = g[j * k + j].sqrt();
        debug_assert!(d > 0.0, "I + C Cᵀ is positive definite");
        g[j * k + j] = d;
        for i in j + 1..k {
            g[j * k + i] /= d;
        }
    }
}

/// `out = Eᵀ w`: out_I = w, out_D = Cᵀ w (C column-major, leading dimension k = |I|).
fn scatter(ind: &[usize], dep: &[usize], c: &[f64], w: &[f64], out: &mut [f64]) {
    let k = ind.len();
    for (a, &i) in ind.iter().enumerate() {
        out[i] = w[a];
    }
    for (e, &d) in dep.iter().enumerate() {
        out[d] = (0..k).map(|a| c[e * k + a] * w[a]).sum();
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

    /// A full-rank S (three independent columns of Y): λ = S⁻¹ r by nalgebra's LU, r̂ = r.
    #[test]
    fn full_rank_is_the_inverse() {
        let y = DMatrix::from_row_slice(
            4,
            3,
            &[1.0, 0.2, 0.0, 0.0, 3.0, 1.0, 0.5, 0.0, 2.0, -1.0, 0.4, 0.1],
        );
        let s = y.transpose() * &y;
        let r = [0.7, -1.5, 2.0];
        let mut solver = MinNormSolver::new(3);
        let mut lambda = [0.0; 3];
        assert_eq!(solver.solve(&s, &r, 1e-12, &mut lambda), 3);
        let expected = s
            .clone()
            .lu()
            .solve(&nalgebra::DVector::from_column_slice(&r))
            .unwrap();
        for i in 0..3 {
            assert!(
                (lambda[i] - expected[i]).abs() < 4e-15,
                "{lambda:?} {expected}"
            );
            assert_eq!(solver.r_hat[i], r[i]);
        }
    }
}
