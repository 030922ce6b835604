//! In-place kernels of the projection on preallocated storage (no allocation): Featherstone's
//! branch-sparse `M = LᵀL` factor, dense triangular solves and a diagonally pivoted Cholesky that
//! finds the independent rows of a constraint Gram matrix.
//!
//! The LTL factor is the one of `dynamics/ltl.rs` (private to that module): `L[k, i] ≠ 0` only when
//! velocity coordinate i is k itself or an ancestor of k (`parent[k]`, `NO_PARENT` at a root).

use nalgebra::DMatrix;

pub(super) const NO_PARENT: usize = usize::MAX;

/// In place: the lower triangle of `m` becomes L with M = Lᵀ L. Fails with the coordinate whose
/// pivot is ≤ `rel_tol · max diag(M)` (M not positive definite).
pub(super) fn ltl_factor(
    m: &mut DMatrix<f64>,
    parent: &[usize],
    rel_tol: f64,
) -> Result<(), usize> {
    let n = m.nrows();
    let scale = (0..n)
        .map(|i| m[(i, i)].abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    for k in (0..n).rev() {
        if m[(k, k)].is_nan() || m[(k, k)] <= rel_tol * scale {
            return Err(k);
        }
        let d = m[(k, k)].sqrt();
        m[(k, k)] = d;
        let mut i = parent[k];
        while i != NO_PARENT {
            m[(k, i)] /= d;
            i = parent[i];
        }
        let mut i = parent[k];
        while i != NO_PARENT {
            let lki = m[(k, i)];
            let mut j = i;
            while j != NO_PARENT {
                m[(i, j)] -= lki * m[(k, j)];
                j = parent[j];
            }
            i = parent[i];
        }
    }
    Ok(())
}

/// Solve `Lᵀ y = x` in place (x → y): leaves first, each result scattered to its ancestors.
/// `inv_diag[k] = 1 / L[k, k]` (a multiply instead of a division on the critical path).
pub(super) fn ltl_solve_lt(l: &DMatrix<f64>, inv_diag: &[f64], parent: &[usize], x: &mut [f64]) {
    for k in (0..x.len()).rev() {
        if x[k] == 0.0 {
            continue;
        }
        let y = x[k] * inv_diag[k];
        x[k] = y;
        let mut i = parent[k];
        while i != NO_PARENT {
            x[i] -= l[(k, i)] * y;
            i = parent[i];
        }
    }
}

/// Solve `L z = y` in place: root first, each row gathering from its ancestors.
pub(super) fn ltl_solve_l(l: &DMatrix<f64>, inv_diag: &[f64], parent: &[usize], y: &mut [f64]) {
    for k in 0..y.len() {
        let mut s = y[k];
        let mut i = parent[k];
        while i != NO_PARENT {
            s -= l[(k, i)] * y[i];
            i = parent[i];
        }
        y[k] = s * inv_diag[k];
    }
}

/// Dense in-place Cholesky `A = L Lᵀ` of the leading n × n block (lower triangle). Fails with the
/// first pivot ≤ `rel_tol · max diag`.
pub(super) fn cholesky(a: &mut DMatrix<f64>, n: usize, rel_tol: f64) -> Result<(), usize> {
    let scale = (0..n)
        .map(|i| a[(i, i)].abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    for j in 0..n {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= a[(j, k)] * a[(j, k)];
        }
        if d.is_nan() || d <= rel_tol * scale {
            return Err(j);
        }
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
    Ok(())
}

/// Solve `L x = b` in place with the leading n × n lower triangle of `l`.
pub(super) fn solve_lower(l: &DMatrix<f64>, n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[(i, k)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
}

/// Solve `Lᵀ x = b` in place with the leading n × n lower triangle of `l`.
pub(super) fn solve_lower_transpose(l: &DMatrix<f64>, n: usize, b: &mut [f64]) {
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[(k, i)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
}

/// Rank-revealing Cholesky of the symmetric leading n × n block of `s` (column-major, leading
/// dimension `ld`, both triangles filled), in place: `P S Pᵀ = [L₁₁; L₂₁] [L₁₁ᵀ L₂₁ᵀ]` up to a
/// residual block that is numerically zero. Rows are taken in order; a row whose remaining pivot
/// is ≤ `rel_tol · S_kk` (the squared sine of its angle to the span of the rows already taken,
/// so the test does not depend on the rows' units) is dependent and is moved to the end. The
/// rows keep their relative order, so constraint rows placed first are tested against each
/// other only, and later rows against the constraints' span. `perm[i]` (in/out) is the original
/// row at position i; `diag0` the original diagonal (permuted along). Returns the rank. No
/// permutation happens when the rows are independent.
pub(super) fn rank_revealing_cholesky(
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
