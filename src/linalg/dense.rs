//! Dense in-place kernels on preallocated matrices (no allocation). Factors and solves act on
//! the leading n × n block, so one workspace serves problems of varying size.

use nalgebra::DMatrix;

/// Dense in-place Cholesky `A = L Lᵀ` of the leading n × n block (lower triangle). Fails with the
/// first pivot ≤ `rel_tol · max diag`.
pub fn cholesky_in_place(a: &mut DMatrix<f64>, n: usize, rel_tol: f64) -> Result<(), usize> {
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
pub fn solve_lower(l: &DMatrix<f64>, n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[(i, k)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
}

/// Solve `Lᵀ x = b` in place with the leading n × n lower triangle of `l`.
pub fn solve_lower_transpose(l: &DMatrix<f64>, n: usize, b: &mut [f64]) {
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[(k, i)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
}

/// Solve `L Lᵀ x = b` in place (leading n × n factor).
pub fn cholesky_solve(l: &DMatrix<f64>, n: usize, b: &mut [f64]) {
    solve_lower(l, n, b);
    solve_lower_transpose(l, n, b);
}

/// `Σ a_i b_i` with four partial sums: one running sum makes every addition wait for the
/// previous one; four independent ones keep the multiplier busy (and vectorize).
pub fn dot_unrolled(a: &[f64], b: &[f64]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let mut s = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum::<f64>();
    let mut acc = [0.0; 4];
    for (x, y) in ca.zip(cb) {
        for ((s, p), q) in acc.iter_mut().zip(x).zip(y) {
            *s += p * q;
        }
    }
    s += (acc[0] + acc[1]) + (acc[2] + acc[3]);
    s
}

/// `out = A x` without allocation.
pub fn mat_vec(a: &DMatrix<f64>, x: &[f64], out: &mut [f64]) {
    for (i, o) in out.iter_mut().enumerate() {
        *o = (0..a.ncols()).map(|k| a[(i, k)] * x[k]).sum();
    }
}

/// `out = Aᵀ x` without allocation.
pub fn mat_tr_vec(a: &DMatrix<f64>, x: &[f64], out: &mut [f64]) {
    for (j, o) in out.iter_mut().enumerate() {
        *o = (0..a.nrows()).map(|k| a[(k, j)] * x[k]).sum();
    }
}

/// `c ← α a b + β c`, allocation-free (nalgebra's `gemm` hands large dynamic
/// products to matrixmultiply, which allocates packing buffers).
pub fn gemm_into(c: &mut DMatrix<f64>, alpha: f64, a: &DMatrix<f64>, b: &DMatrix<f64>, beta: f64) {
    gemm_columns(c, alpha, a, b, beta, b.ncols());
}

/// `c[:, ..ncols] ← α a b[:, ..ncols] + β c[:, ..ncols]`, allocation-free: column by column
/// as sums of a's columns (contiguous in nalgebra's column-major storage, so the inner loop
/// vectorizes and needs no bounds checks).
pub fn gemm_columns(
    c: &mut DMatrix<f64>,
    alpha: f64,
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    beta: f64,
    ncols: usize,
) {
    let (m, kdim) = a.shape();
    assert!(b.nrows() == kdim && c.nrows() == m && ncols <= b.ncols() && ncols <= c.ncols());
    if m == 0 {
        return;
    }
    let (a_s, b_s) = (a.as_slice(), b.as_slice());
    for (j, cj) in c.as_mut_slice().chunks_exact_mut(m).take(ncols).enumerate() {
        if beta == 0.0 {
            cj.fill(0.0);
        } else if beta != 1.0 {
            cj.iter_mut().for_each(|x| *x *= beta);
        }
        let bj = &b_s[j * kdim..(j + 1) * kdim];
        // Four of a's columns per pass over c's column: a quarter of the loads and stores
        // of c, which dominate at the small sizes here (nv ~ 10).
        let mut k = 0;
        while k + 4 <= kdim {
            let s = [
                alpha * bj[k],
                alpha * bj[k + 1],
                alpha * bj[k + 2],
                alpha * bj[k + 3],
            ];
            let a4 = &a_s[k * m..(k + 4) * m];
            let (a0, rest) = a4.split_at(m);
            let (a1, rest) = rest.split_at(m);
            let (a2, a3) = rest.split_at(m);
            for i in 0..m {
                cj[i] += a0[i] * s[0] + a1[i] * s[1] + a2[i] * s[2] + a3[i] * s[3];
            }
            k += 4;
        }
        for k in k..kdim {
            let s = alpha * bj[k];
            for (ci, ai) in cj.iter_mut().zip(&a_s[k * m..(k + 1) * m]) {
                *ci += ai * s;
            }
        }
    }
}

/// `c ← α aᵀ b + β c`, naive and allocation-free.
pub fn gemm_tr_into(
    c: &mut DMatrix<f64>,
    alpha: f64,
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    beta: f64,
) {
    debug_assert_eq!(a.nrows(), b.nrows());
    debug_assert_eq!((c.nrows(), c.ncols()), (a.ncols(), b.ncols()));
    for j in 0..b.ncols() {
        for i in 0..a.ncols() {
            let mut s = 0.0;
            for k in 0..a.nrows() {
                s += a[(k, i)] * b[(k, j)];
            }
            c[(i, j)] = alpha * s + if beta == 0.0 { 0.0 } else { beta * c[(i, j)] };
        }
    }
}
