//! The minimum-norm solution λ = S⁺ r of a Gram system S λ = r (S = YᵀY, n × n, positive
//! semi-definite, possibly singular), on a preallocated workspace: the multipliers of every
//! constraint set, redundant and singular ones included.
//!
//! A plain Cholesky factor of S is tried first: when every pivot is above `tol` · max diag(S),
//! λ = S⁻¹ r. Otherwise a Cholesky factorization with diagonal pivoting,
//! `P S Pᵀ = [L₁₁; L₂₁][L₁₁ᵀ L₂₁ᵀ]`, takes at each step the largest remaining pivot — the column
//! of Y farthest from the span of those taken (column-pivoted QR of Y, done on S) — and stops
//! when it is ≤ `tol` · max diag(S): that gives a maximal independent set I (k columns) and the
//! dependent rest D, Y_D = Y_I C with
//! C = S_II⁻¹ S_ID = L₁₁⁻ᵀ L₂₁ᵀ. So Y = Y_I E with E = [I C] (columns in (I, D) order) of full row
//! rank, S = Eᵀ S_II E and
//!   S⁺ = Eᵀ G⁻¹ S_II⁻¹ G⁻¹ E,  G = E Eᵀ = I + C Cᵀ,
//! (the pseudo-inverse of a full-column-rank times a full-row-rank product). The projection of r
//! on range(S) = range(Eᵀ) is r̂ = Eᵀ G⁻¹ E r; what is left, r − r̂, is the part of the right side
//! no λ can meet. S⁺ is unique, so λ is smooth in S whichever independent set was picked. When
//! S has full rank (k = n) this is λ = S⁻¹ r, and r̂ = r. Why not keep the in-order factor
//! where it fails and pivot from there (it fails at its last pivot on every wheeled scene, two
//! wheels' lateral rows being one row, and that work is lost): an independent set taken in order
//! can hold a nearly dependent row that the largest-first order leaves for last, and on the
//! floating mobile manipulator that moved the RK4 step's derivative along the base's roll from
//! its finite differences by 1.6e-5 (tests/it/linearize.rs, bar 1e-8).
//!
//! The matrices are a few rows wide (one per constraint row), so they live in flat column-major
//! buffers indexed directly: nalgebra's indexing and row swaps cost more than the arithmetic.

use super::dense::{
    cholesky_in, solve_lower_in, solve_lower_transpose_in, subtract_earlier_columns,
};
use crate::linalg::by_size;
use nalgebra::DMatrix;

/// Workspace of [`MinNormSolver::solve`] for n × n systems.
#[derive(Clone, Debug, Default)]
pub struct MinNormSolver {
    n: usize,
    /// P S Pᵀ (lower triangle), then its pivoted factor (L₁₁ leading k × k, L₂₁ below);
    /// column-major, leading dimension n.
    l: Vec<f64>,
    /// perm[i]: the row of S at pivoted position i (I = perm[..k], D = perm[k..]).
    perm: Vec<usize>,
    /// C (k × (n − k)) and the factor of G (k × k), column-major, leading dimension k.
    c: Vec<f64>,
    g: Vec<f64>,
    w: Vec<f64>,
    /// The remaining pivots during the factorization (n).
    pivots: Vec<f64>,
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
            pivots: vec![0.0; n],
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
            solve_lower_in(&self.l, n, k, w);
            solve_lower_transpose_in(&self.l, n, k, w);
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
            solve_lower_transpose_in(l, n, k, col);
        }
        // G = I + C Cᵀ (positive definite whatever C is), factored in place.
        for b in 0..k {
            for a in b..k {
                let cc: f64 = (0..nd).map(|e| c[e * k + a] * c[e * k + b]).sum();
                g[b * k + a] = cc + if a == b { 1.0 } else { 0.0 };
            }
        }
        let factored = cholesky_in(g, k, k, 0.0);
        debug_assert!(factored.is_ok(), "I + C Cᵀ is positive definite");
        // w = G⁻¹ E r;  r̂ = Eᵀ w.
        for (a, wa) in w.iter_mut().enumerate() {
            *wa += (0..nd).map(|e| c[e * k + a] * r[dep[e]]).sum::<f64>();
        }
        solve_lower_in(g, k, k, w);
        solve_lower_transpose_in(g, k, k, w);
        scatter(ind, dep, c, w, &mut self.r_hat);
        // λ = Eᵀ G⁻¹ S_II⁻¹ w.
        solve_lower_in(l, n, k, w);
        solve_lower_transpose_in(l, n, k, w);
        solve_lower_in(g, k, k, w);
        solve_lower_transpose_in(g, k, k, w);
        scatter(ind, dep, c, w, lambda);
        k
    }

    /// `S = L Lᵀ` in order if every pivot passes, else `P S Pᵀ = L Lᵀ` with the largest
    /// remaining pivot first, stopping when it is ≤ `tol` · max diag(S); into `l` (lower
    /// triangle) and `perm`. Returns the rank.
    fn pivoted_cholesky(&mut self, s: &DMatrix<f64>, tol: f64) -> usize {
        let n = self.n;
        let (l, perm) = (&mut self.l, &mut self.perm);
        let k = by_size!(n, factor_in_order_fixed(s, tol, l, perm), {
            self.factor(s, tol, false)
        });
        if k == n { n } else { self.factor(s, tol, true) }
    }

    /// One attempt: S's lower triangle copied into `l`, `perm` reset, then [`factor_pivoted`].
    fn factor(&mut self, s: &DMatrix<f64>, tol: f64, largest_first: bool) -> usize {
        let n = self.n;
        let (src, lds) = (s.as_slice(), s.nrows());
        for c in 0..n {
            self.l[c * n + c..c * n + n].copy_from_slice(&src[c * lds + c..c * lds + n]);
        }
        self.perm.clear();
        self.perm.extend(0..n);
        factor_pivoted(
            &mut self.l,
            n,
            &mut self.perm,
            &mut self.pivots,
            tol,
            largest_first,
        )
    }
}

/// [`MinNormSolver::factor`] in order for n = N known when compiled: the same operations in the
/// same order as [`factor_pivoted`] (so the same factor to the bit), on loops of known length; a
/// few constraint rows spend more in the general loops' control than in their arithmetic.
fn factor_in_order_fixed<const N: usize>(
    s: &DMatrix<f64>,
    tol: f64,
    l: &mut [f64],
    perm: &mut Vec<usize>,
) -> usize {
    let (src, lds) = (s.as_slice(), s.nrows());
    let l = &mut l[..N * N];
    for c in 0..N {
        l[c * N + c..c * N + N].copy_from_slice(&src[c * lds + c..c * lds + N]);
    }
    perm.clear();
    perm.extend(0..N);
    let dmax = (0..N).fold(0.0, |m: f64, i| m.max(l[i * N + i]));
    for j in 0..N {
        // Column j less the earlier columns, each subtraction in factor_pivoted's order.
        for k in 0..j {
            let f = l[k * N + j];
            for r in j..N {
                l[j * N + r] -= f * l[k * N + r];
            }
        }
        let pivot = l[j * N + j];
        if pivot.is_nan() || pivot <= tol * dmax {
            return j;
        }
        let d = pivot.sqrt();
        l[j * N + j] = d;
        for r in j + 1..N {
            l[j * N + r] /= d;
        }
    }
    N
}

wide_fn! {
/// The factors of [`MinNormSolver::pivoted_cholesky`] on the lower triangle of the column-major
/// n × n `l`, left-looking as `dense::cholesky_in_place` (column j is S's column less the
/// earlier columns of L, each a contiguous segment: the loops vectorize), with the remaining
/// pivots S_ii − Σ_k L_ik² kept in `pivots` (n): in order (stopping at the first that fails),
/// or the largest remaining first.
fn factor_pivoted(
    l: &mut [f64],
    n: usize,
    perm: &mut [usize],
    pivots: &mut [f64],
    tol: f64,
    largest_first: bool,
) -> usize {
    for (i, d) in pivots.iter_mut().enumerate() {
        *d = l[i * n + i];
    }
    let dmax = pivots.iter().fold(0.0, |m: f64, &d| m.max(d));
    for j in 0..n {
        let p = if largest_first {
            (j + 1..n).fold(j, |p, i| if pivots[i] > pivots[p] { i } else { p })
        } else {
            j
        };
        let pivot = pivots[p];
        if pivot.is_nan() || pivot <= tol * dmax {
            return j;
        }
        if p != j {
            symmetric_swap(l, n, j, p);
            perm.swap(p, j);
            pivots.swap(p, j);
        }
        let col = subtract_earlier_columns(l, n, n, j);
        // col[0] is the pivot again, by the same subtractions in the same order.
        let d = col[0].sqrt();
        col[0] = d;
        for (c, r) in col[1..].iter_mut().zip(&mut pivots[j + 1..]) {
            *c /= d;
            *r -= *c * *c;
        }
    }
    n
}
}

/// Exchange rows and columns j < p of the symmetric matrix stored in the lower triangle of the
/// column-major n × n `l` (LAPACK's `dsyswapr`): the factored columns' rows j and p, the two
/// diagonal entries, and the entries of columns ≥ j that meet row or column j or p.
fn symmetric_swap(l: &mut [f64], n: usize, j: usize, p: usize) {
    let at = |r: usize, c: usize| c * n + r;
    l.swap(at(j, j), at(p, p));
    for k in 0..j {
        l.swap(at(j, k), at(p, k));
    }
    for i in j + 1..p {
        l.swap(at(i, j), at(p, i));
    }
    for i in p + 1..n {
        l.swap(at(i, j), at(i, p));
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
                (lambda[i] - expected[i]).abs() < 4.4e-16, // achieved 1.1e-16 (one ulp)
                "{lambda:?} {expected}"
            );
            assert_eq!(solver.r_hat[i], r[i]);
        }
    }

    /// Six columns of growing length, two of them combinations of others (rank 4): the
    /// largest-pivot-first order reverses them, so every kind of symmetric swap runs. Against
    /// the SVD pseudo-inverse (achieved 1.1e-15 and 6.5e-16 of the largest entry).
    #[test]
    fn pivots_through_many_swaps() {
        let mut y = DMatrix::from_fn(7, 6, |i, j| {
            (j as f64 + 1.0) * (((i * 7 + j * 13 + i * j) % 11) as f64 - 5.0)
        });
        let dep = y.column(0) * 2.0 - y.column(3) * 0.5;
        y.set_column(1, &dep);
        let dep = y.column(5) * 0.25 + y.column(2);
        y.set_column(4, &dep);
        let s = y.transpose() * &y;
        let r = [0.3, -1.0, 0.8, 2.0, -0.4, 1.1];
        let mut solver = MinNormSolver::new(6);
        let mut lambda = [0.0; 6];
        assert_eq!(solver.solve(&s, &r, 1e-12, &mut lambda), 4);
        let pinv = s.clone().pseudo_inverse(1e-9).unwrap();
        let expected = &pinv * nalgebra::DVector::from_column_slice(&r);
        let r_hat = &s * &expected;
        let scale = expected.amax();
        for i in 0..6 {
            assert!(
                (lambda[i] - expected[i]).abs() < 5e-15 * scale,
                "{lambda:?} {expected}"
            );
            assert!((solver.r_hat[i] - r_hat[i]).abs() < 3e-15 * r_hat.amax());
        }
    }
}
