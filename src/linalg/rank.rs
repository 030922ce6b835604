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

/// Solve `L Lᵀ x = b` in place with the factor of [`semidefinite_cholesky`] (x_j = 0 where dropped).
pub fn semidefinite_solve(l: &DMatrix<f64>, dropped: &[bool], b: &mut [f64]) {
    let n = l.nrows();
    for i in 0..n {
        if dropped[i] {
            b[i] = 0.0;
            continue;
        }
        let mut s = b[i];
        for k in 0..i {
            s -= l[(i, k)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
    for i in (0..n).rev() {
        if dropped[i] {
            b[i] = 0.0;
            continue;
        }
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[(k, i)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
}
