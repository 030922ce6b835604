//! Small in-place dense kernels for the integrators (no allocation).

use nalgebra::DMatrix;

/// LU with partial pivoting in place, `P A = L U` (unit L below the diagonal, U on and above it),
/// `piv[k]` the row swapped with k at step k. False when a pivot is zero or not finite.
pub fn lu_in_place(a: &mut DMatrix<f64>, piv: &mut [usize]) -> bool {
    let n = a.nrows();
    for k in 0..n {
        let (mut p, mut best) = (k, a[(k, k)].abs());
        for r in k + 1..n {
            if a[(r, k)].abs() > best {
                (p, best) = (r, a[(r, k)].abs());
            }
        }
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        piv[k] = p;
        if p != k {
            a.swap_rows(p, k);
        }
        let d = a[(k, k)];
        for r in k + 1..n {
            let l = a[(r, k)] / d;
            a[(r, k)] = l;
            if l != 0.0 {
                for c in k + 1..n {
                    a[(r, c)] -= l * a[(k, c)];
                }
            }
        }
    }
    true
}

/// Solve `A x = b` in place with the factor of [`lu_in_place`].
pub fn lu_solve(lu: &DMatrix<f64>, piv: &[usize], b: &mut [f64]) {
    let n = lu.nrows();
    for k in 0..n {
        b.swap(k, piv[k]);
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= lu[(i, k)] * b[k];
        }
        b[i] = s;
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= lu[(i, k)] * b[k];
        }
        b[i] = s / lu[(i, i)];
    }
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
