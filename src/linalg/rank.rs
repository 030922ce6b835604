//! Rank-revealing factorizations: a diagonally pivoted Cholesky that finds the independent rows of
//! a Gram matrix (projection), and a semi-definite Cholesky that drops dependent columns (drift
//! projection and least-squares constraint accelerations).

use nalgebra::DMatrix;

/// Rank-revealing Cholesky of the symmetric leading n × n block of `s` (column-major, leading
/// dimension `ld`, both triangles filled), in place: `P S Pᵀ = [L₁₁; L₂₁] [L₁₁ᵀ L₂₁ᵀ]` up to a
/// residual block that is numerically zero. Rows are taken in order; a row whose remaining pivot
/// is ≤ `rel_tol · S_kk` (the squared sine of its angle to the span of the rows already taken,
/// so the test does not depend on the rows' units) is dependent and is moved to the end. The
/// rows keep their relative order, so constraint rows placed first are tested against each
/// other only, and later rows against the constraints' span. `perm[i]` (in/out) is the original
/// row at position i; `diag0` the original diagonal (permuted along). Returns the rank. No
/// permutation happens when the rows are independent.
pub fn rank_revealing_cholesky(
    s: &mut [f64],
    ld: usize,
    n: usize,
    perm: &mut [usize],
    diag0: &mut [f64],
    rel_tol: f64,
) -> usize {
    let mut end = n; // rows end.. are dependent
    let mut j = 0;
    while j < end {
        let pivot = s[j * ld + j];
        if !(diag0[j] > 0.0 && pivot > rel_tol * diag0[j]) {
            // Move row/column j to position n − 1, shifting j+1..n up by one.
            for c in 0..n {
                let col = &mut s[c * ld..c * ld + n];
                col[j..n].rotate_left(1);
            }
            for r in 0..n {
                let t = s[j * ld + r];
                for c in j..n - 1 {
                    s[c * ld + r] = s[(c + 1) * ld + r];
                }
                s[(n - 1) * ld + r] = t;
            }
            perm[j..n].rotate_left(1);
            diag0[j..n].rotate_left(1);
            end -= 1;
            continue;
        }
        let d = pivot.sqrt();
        s[j * ld + j] = d;
        let inv = 1.0 / d;
        for i in j + 1..n {
            s[j * ld + i] *= inv;
        }
        for c in j + 1..n {
            let lcj = s[j * ld + c];
            if lcj == 0.0 {
                continue;
            }
            for i in c..n {
                let v = s[c * ld + i] - s[j * ld + i] * lcj;
                s[c * ld + i] = v;
                s[i * ld + c] = v;
            }
        }
        j += 1;
    }
    end
}

/// Cholesky of a positive semi-definite matrix in place (`A = L Lᵀ`, lower triangle written),
/// dropping every column whose pivot is ≤ `rel_tol · max diag(A)` (its row and column of L are
/// zeroed and `dropped[j]` set). Returns the rank. Solving with [`semidefinite_solve`] then gives
/// the solution of `A x = b` with x_j = 0 on the dropped columns, exact when b ∈ range(A).
pub fn semidefinite_cholesky(a: &mut DMatrix<f64>, rel_tol: f64, dropped: &mut [bool]) -> usize {
    let n = a.nrows();
    let scale = (0..n)
        .map(|i| a[(i, i)].abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let mut rank = 0;
    for j in 0..n {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= a[(j, k)] * a[(j, k)];
        }
        if d.is_nan() || d <= rel_tol * scale {
            dropped[j] = true;
            for i in j..n {
                a[(i, j)] = 0.0;
            }
            continue;
        }
        dropped[j] = false;
        rank += 1;
        let d = d.sqrt();
        a[(j, j)] = d;
        for i in j + 1..n {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= a[(i, k)] * a[(j, k)];
            }
            a[(i, j)] = s / d;
        }
    }
    rank
}

wide_fn! {
/// [`semidefinite_solve`] for every column of `b` at once. Row by row over all columns, so the
/// divisions by the pivots of different columns overlap instead of each column's solve waiting
/// on its own chain of divisions (3× faster for 38 columns of 12 rows).
pub fn semidefinite_solve_columns(l: &DMatrix<f64>, dropped: &[bool], b: &mut DMatrix<f64>) {
    let n = l.nrows();
    assert_eq!(b.nrows(), n);
    let s = l.as_slice();
    let cols = b.ncols();
    let bs = b.as_mut_slice();
    for k in 0..n {
        if dropped[k] {
            for c in 0..cols {
                bs[c * n + k] = 0.0;
            }
            continue;
        }
        // One division per row, not per column (a product by the reciprocal differs from the
        // quotient by at most an ulp).
        let inv = 1.0 / s[k * n + k];
        let lk = &s[k * n + k + 1..(k + 1) * n];
        for bc in bs.chunks_exact_mut(n) {
            let bk = bc[k] * inv;
            bc[k] = bk;
            for (bi, lik) in bc[k + 1..].iter_mut().zip(lk) {
                *bi -= bk * lik;
            }
        }
    }
    for i in (0..n).rev() {
        let li = &s[i * n + i + 1..(i + 1) * n];
        let inv = 1.0 / s[i * n + i];
        for bc in bs.chunks_exact_mut(n) {
            bc[i] = if dropped[i] {
                0.0
            } else {
                (bc[i] - super::dot_unrolled(li, &bc[i + 1..])) * inv
            };
        }
    }
}
}

/// Solve `L Lᵀ x = b` in place with the factor of [`semidefinite_cholesky`] (x_j = 0 where dropped).
pub fn semidefinite_solve(l: &DMatrix<f64>, dropped: &[bool], b: &mut [f64]) {
    let n = l.nrows();
    let s = l.as_slice();
    // L y = b by columns of L (contiguous): each solved entry updates the ones below it.
    for k in 0..n {
        if dropped[k] {
            b[k] = 0.0;
            continue;
        }
        let bk = b[k] / s[k * n + k];
        b[k] = bk;
        for (bi, lik) in b[k + 1..n].iter_mut().zip(&s[k * n + k + 1..(k + 1) * n]) {
            *bi -= bk * lik;
        }
    }
    // Lᵀ x = y: entry i from column i of L below the diagonal (contiguous) and the x below.
    for i in (0..n).rev() {
        if dropped[i] {
            b[i] = 0.0;
            continue;
        }
        let dot = super::dot_unrolled(&s[i * n + i + 1..(i + 1) * n], &b[i + 1..n]);
        b[i] = (b[i] - dot) / s[i * n + i];
    }
}
