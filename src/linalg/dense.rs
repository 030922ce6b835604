//! Dense in-place kernels on preallocated matrices (no allocation). Factors and solves act on
//! the leading n × n block, so one workspace serves problems of varying size.

use nalgebra::DMatrix;

/// Dense in-place Cholesky `A = L Lᵀ` of the leading n × n block (lower triangle). Fails with the
/// first pivot ≤ `rel_tol · max diag`. Left-looking by columns: column j of L is A's column j
/// minus L's earlier columns, each a contiguous slice of the column-major storage (the loops
/// vectorize); each entry's sum runs over k in increasing order, as the textbook form does.
pub fn cholesky_in_place(a: &mut DMatrix<f64>, n: usize, rel_tol: f64) -> Result<(), usize> {
    let ld = a.nrows();
    cholesky_in(a.as_mut_slice(), ld, n, rel_tol)
}

wide_fn! {
/// [`cholesky_in_place`] on column-major storage `s` of leading dimension `ld`.
pub(crate) fn cholesky_in(s: &mut [f64], ld: usize, n: usize, rel_tol: f64) -> Result<(), usize> {
    let scale = (0..n)
        .map(|i| s[i * ld + i].abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    for j in 0..n {
        let col = subtract_earlier_columns(s, ld, n, j);
        let d = col[0];
        if d.is_nan() || d <= rel_tol * scale {
            return Err(j);
        }
        let d = d.sqrt();
        col[0] = d;
        for c in &mut col[1..] {
            *c /= d;
        }
    }
    Ok(())
}
}

/// The left-looking step of a Cholesky factor in the column-major `s` (leading dimension `ld`):
/// column j's rows j..n less Σ_k L[j,k] L[j.., k] over the finished columns k < j, each a
/// contiguous segment, k increasing. Returns that segment (its first entry is the pivot).
/// Inlined into its callers' AVX2 builds.
#[inline(always)]
pub(crate) fn subtract_earlier_columns(s: &mut [f64], ld: usize, n: usize, j: usize) -> &mut [f64] {
    let (done, rest) = s.split_at_mut(j * ld);
    let col = &mut rest[j..n];
    for k in 0..j {
        let lk = &done[k * ld + j..k * ld + n];
        let f = lk[0];
        for (c, l) in col.iter_mut().zip(lk) {
            *c -= f * l;
        }
    }
    col
}

wide_fn! {
/// The inverse of the symmetric positive-definite leading n × n block of `a` into the leading
/// block of `out` (both triangles), allocation-free; `a`'s block is overwritten (by L⁻¹ of its
/// Cholesky factor). Fails with the first pivot ≤ `rel_tol · max diag`. A⁻¹ = L⁻ᵀ L⁻¹: the
/// factor (n³/6 multiply-adds), its inverse in place (n³/6) and the product (n³/6), all on
/// contiguous column slices — a third of the work of solving for the n unit vectors.
pub fn spd_inverse(
    a: &mut DMatrix<f64>,
    n: usize,
    rel_tol: f64,
    out: &mut DMatrix<f64>,
) -> Result<(), usize> {
    cholesky_in_place(a, n, rel_tol)?;
    inverse_from_cholesky(a, n, out);
    Ok(())
}
}

wide_fn! {
/// A⁻¹ into the leading n × n block of `out` (both triangles) from the Cholesky factor L of A
/// in the lower triangle of `a`'s leading block, which becomes L⁻¹ (see [`spd_inverse`]).
pub fn inverse_from_cholesky(a: &mut DMatrix<f64>, n: usize, out: &mut DMatrix<f64>) {
    let ld = a.nrows();
    let s = a.as_mut_slice();
    // L⁻¹ in place, last column first: column j of L⁻¹ is −(L⁻¹)_jj · T x, with x the column
    // below the diagonal and T the already inverted trailing block.
    for j in (0..n).rev() {
        let (head, tail) = s.split_at_mut((j + 1) * ld);
        let djj = 1.0 / head[j * ld + j];
        head[j * ld + j] = djj;
        let x = &mut head[j * ld + j + 1..j * ld + n];
        for k in (j + 1..n).rev() {
            let tk = &tail[(k - j - 1) * ld + k..(k - j - 1) * ld + n];
            let xk = x[k - j - 1];
            for (xi, t) in x[k - j..].iter_mut().zip(&tk[1..]) {
                *xi += xk * t;
            }
            x[k - j - 1] = xk * tk[0];
        }
        for xi in x.iter_mut() {
            *xi *= -djj;
        }
    }
    // A⁻¹ = Wᵀ W with W = L⁻¹ lower: (a, b) = Σ_{k ≥ a} W_ka W_kb for a ≥ b.
    for b in 0..n {
        for r in b..n {
            let x = dot_unrolled(&s[r * ld + r..r * ld + n], &s[b * ld + r..b * ld + n]);
            out[(r, b)] = x;
            out[(b, r)] = x;
        }
    }
}
}

/// Solve `L x = b` in place with the leading n × n lower triangle of `l`.
pub fn solve_lower(l: &DMatrix<f64>, n: usize, b: &mut [f64]) {
    solve_lower_in(l.as_slice(), l.nrows(), n, b)
}

/// Solve `Lᵀ x = b` in place with the leading n × n lower triangle of `l`.
pub fn solve_lower_transpose(l: &DMatrix<f64>, n: usize, b: &mut [f64]) {
    solve_lower_transpose_in(l.as_slice(), l.nrows(), n, b)
}

/// [`solve_lower`] on column-major storage `l` of leading dimension `ld`.
pub(crate) fn solve_lower_in(l: &[f64], ld: usize, n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[k * ld + i] * b[k];
        }
        b[i] = s / l[i * ld + i];
    }
}

/// [`solve_lower_transpose`] on column-major storage `l` of leading dimension `ld`.
pub(crate) fn solve_lower_transpose_in(l: &[f64], ld: usize, n: usize, b: &mut [f64]) {
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[i * ld + k] * b[k];
        }
        b[i] = s / l[i * ld + i];
    }
}

/// Solve `L Lᵀ x = b` in place (leading n × n factor).
pub fn cholesky_solve(l: &DMatrix<f64>, n: usize, b: &mut [f64]) {
    solve_lower(l, n, b);
    solve_lower_transpose(l, n, b);
}

/// `Σ a_i b_i` with four partial sums: one running sum makes every addition wait for the
/// previous one; four independent ones keep the multiplier busy (and vectorize).
#[inline]
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
    mat_vec_add(a, x, 0.0, out);
}

/// `out = A x + β out` over A's first `out.len()` rows, without allocation: as sums of A's
/// columns (contiguous; the loop vectorizes, where a dot product per row strides through memory).
/// Each entry's sum runs over k in increasing order.
pub fn mat_vec_add(a: &DMatrix<f64>, x: &[f64], beta: f64, out: &mut [f64]) {
    let (m, n) = (a.nrows(), out.len());
    assert!(n <= m && x.len() >= a.ncols());
    if beta == 0.0 {
        out.fill(0.0);
    } else if beta != 1.0 {
        out.iter_mut().for_each(|o| *o *= beta);
    }
    if m == 0 {
        return;
    }
    for (col, &xk) in a.as_slice().chunks_exact(m).zip(x) {
        for (o, aik) in out.iter_mut().zip(&col[..n]) {
            *o += aik * xk;
        }
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

/// `c[:, ..ncols] ← α a b[:, ..ncols] + β c[:, ..ncols]`, allocation-free. On a CPU with AVX2
/// and FMA, the register-blocked kernel of `gemm_avx2.rs` (C's 8 × 4 tiles held in registers
/// over the k loop: talos_reduced's ABA derivatives, two 38 × 38 × 38 products and their
/// recursions, take 34 µs with it against 45 µs column by column); elsewhere column by column as
/// sums of a's columns (contiguous in nalgebra's column-major storage, so the inner loop
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
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        let (a_s, b_s) = (a.as_slice(), b.as_slice());
        // SAFETY: the CPU has AVX2 and FMA (checked just above); the shapes are asserted
        // above, so the slices hold m·kdim, kdim·ncols and m·ncols values.
        unsafe {
            super::gemm_avx2::gemm(c.as_mut_slice(), alpha, a_s, b_s, beta, (m, kdim, ncols));
        }
        return;
    }
    gemm_kernel(c, alpha, a, b, beta, ncols)
}

/// The portable column sums of [`gemm_columns`] (shapes checked there).
fn gemm_kernel(
    c: &mut DMatrix<f64>,
    alpha: f64,
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    beta: f64,
    ncols: usize,
) {
    let (m, kdim) = a.shape();
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
                let x = a0[i] * s[0] + a1[i] * s[1];
                let y = a2[i] * s[2] + a3[i] * s[3];
                cj[i] += x + y;
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

wide_fn! {
/// `c ← α aᵀ b + β c`, allocation-free: each entry a dot product of two columns (contiguous).
pub fn gemm_tr_into(
    c: &mut DMatrix<f64>,
    alpha: f64,
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    beta: f64,
) {
    let k = a.nrows();
    assert!(b.nrows() == k && c.nrows() == a.ncols() && c.ncols() == b.ncols());
    let (a_s, b_s) = (a.as_slice(), b.as_slice());
    let m = c.nrows();
    for (j, cj) in c.as_mut_slice().chunks_exact_mut(m.max(1)).enumerate().take(b.ncols()) {
        let bj = &b_s[j * k..(j + 1) * k];
        for (i, cij) in cj.iter_mut().enumerate() {
            let d = alpha * dot_unrolled(&a_s[i * k..(i + 1) * k], bj);
            *cij = d + if beta == 0.0 { 0.0 } else { beta * *cij };
        }
    }
}
}

wide_fn! {
/// `c ← α a bᵀ + β c`, allocation-free: c's columns as sums of a's columns (contiguous), as
/// [`gemm_columns`], with b read by rows.
pub fn gemm_nt_into(
    c: &mut DMatrix<f64>,
    alpha: f64,
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    beta: f64,
) {
    let (m, kdim) = a.shape();
    assert!(b.ncols() == kdim && c.nrows() == m && c.ncols() == b.nrows());
    if m == 0 {
        return;
    }
    let a_s = a.as_slice();
    for (j, cj) in c.as_mut_slice().chunks_exact_mut(m).enumerate() {
        if beta == 0.0 {
            cj.fill(0.0);
        } else if beta != 1.0 {
            cj.iter_mut().for_each(|x| *x *= beta);
        }
        for k in 0..kdim {
            let s = alpha * b[(j, k)];
            for (ci, ai) in cj.iter_mut().zip(&a_s[k * m..(k + 1) * m]) {
                *ci += ai * s;
            }
        }
    }
}
}
