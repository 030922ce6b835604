//! Register-blocked `C[:, ..n] ← α A B[:, ..n] + β C[:, ..n]` for x86-64 with AVX2 and FMA.
//!
//! The column-sum loop of [`super::gemm_columns`]'s portable path reads and writes C once per
//! four columns of A; at the sizes here (nv = 9..38) that traffic, not the arithmetic, bounds
//! it. This kernel keeps an 8 × 4 tile of C in eight registers over the whole k loop: per k, two
//! loads of A's column, four broadcasts of B's entries and eight fused multiply-adds, and C is
//! read and written once. Rows past the last multiple of 4 use masked loads and stores (no read
//! or write outside the matrix); columns past the last multiple of 4 use narrower tiles.
//!
//! Each entry is `α · Σ_k a_ik b_kj` summed in increasing k with one rounding per term, then
//! `+ β c_ij` (C is not read when β = 0, so it may hold anything, as BLAS allows).

use std::arch::x86_64::{
    __m256d, __m256i, _mm256_broadcast_sd, _mm256_fmadd_pd, _mm256_loadu_pd, _mm256_maskload_pd,
    _mm256_maskstore_pd, _mm256_mul_pd, _mm256_set1_pd, _mm256_setr_epi64x, _mm256_setzero_pd,
    _mm256_storeu_pd,
};

/// The product on raw column-major storage: A is m × kdim, B kdim × (≥ ncols), C m × (≥ ncols),
/// all with leading dimension equal to their row count.
///
/// # Safety
/// The CPU has AVX2 and FMA; `a`, `b`, `c` hold at least m·kdim, kdim·ncols and m·ncols values.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn gemm(
    c: &mut [f64],
    alpha: f64,
    a: &[f64],
    b: &[f64],
    beta: f64,
    (m, kdim, ncols): (usize, usize, usize),
) {
    debug_assert!(a.len() >= m * kdim && b.len() >= kdim * ncols && c.len() >= m * ncols);
    let p = Panel {
        a: a.as_ptr(),
        m,
        kdim,
        alpha,
        beta,
    };
    let (b, c) = (b.as_ptr(), c.as_mut_ptr());
    let mut j = 0;
    // SAFETY (all calls below): columns j..j+NC < ncols of B and C, rows within m (tiles).
    unsafe {
        while j + 4 <= ncols {
            p.columns::<4>(b.add(j * kdim), c.add(j * m));
            j += 4;
        }
        match ncols - j {
            3 => p.columns::<3>(b.add(j * kdim), c.add(j * m)),
            2 => p.columns::<2>(b.add(j * kdim), c.add(j * m)),
            1 => p.columns::<1>(b.add(j * kdim), c.add(j * m)),
            _ => {}
        }
    }
}

/// A with the scalars of the product.
struct Panel {
    a: *const f64,
    m: usize,
    kdim: usize,
    alpha: f64,
    beta: f64,
}

impl Panel {
    /// NC columns of C (starting at `c`) from the same columns of B (starting at `b`): tiles of
    /// 8 rows, then the rest (1..=7 rows, the last vector masked where it is partial).
    #[inline(always)]
    unsafe fn columns<const NC: usize>(&self, b: *const f64, c: *mut f64) {
        let m = self.m;
        let mut i = 0;
        // SAFETY: every tile covers rows i..i + 4·NV ≤ m, its last vector masked to m.
        unsafe {
            while i + 8 <= m {
                self.tile::<NC, 2, false>(i, b, c, full_mask());
                i += 8;
            }
            let rest = m - i;
            match rest {
                0 => {}
                1..=3 => self.tile::<NC, 1, true>(i, b, c, tail_mask(rest)),
                4 => self.tile::<NC, 1, false>(i, b, c, full_mask()),
                _ => self.tile::<NC, 2, true>(i, b, c, tail_mask(rest - 4)),
            }
        }
    }

    /// Rows i..i + 4·NV of NC columns; with MASKED the last vector holds only `mask`'s lanes.
    #[inline(always)]
    unsafe fn tile<const NC: usize, const NV: usize, const MASKED: bool>(
        &self,
        i: usize,
        b: *const f64,
        c: *mut f64,
        mask: __m256i,
    ) {
        let (m, kdim) = (self.m, self.kdim);
        // SAFETY: rows i..i + 4·NV (the last vector masked) of columns < NC; k < kdim.
        unsafe {
            let mut acc = [[_mm256_setzero_pd(); NV]; NC];
            for k in 0..kdim {
                let ak = self.a.add(k * m + i);
                let mut av = [_mm256_setzero_pd(); NV];
                for (v, x) in av.iter_mut().enumerate() {
                    *x = load::<MASKED>(ak.add(4 * v), mask, v + 1 == NV);
                }
                for (jj, acc_j) in acc.iter_mut().enumerate() {
                    let bk = _mm256_broadcast_sd(&*b.add(jj * kdim + k));
                    for (s, x) in acc_j.iter_mut().zip(&av) {
                        *s = _mm256_fmadd_pd(*x, bk, *s);
                    }
                }
            }
            let alpha = _mm256_set1_pd(self.alpha);
            let beta = _mm256_set1_pd(self.beta);
            for (jj, acc_j) in acc.iter().enumerate() {
                let cj = c.add(jj * m + i);
                for (v, s) in acc_j.iter().enumerate() {
                    let last = v + 1 == NV;
                    let mut x = _mm256_mul_pd(*s, alpha);
                    if self.beta != 0.0 {
                        x = _mm256_fmadd_pd(load::<MASKED>(cj.add(4 * v), mask, last), beta, x);
                    }
                    store::<MASKED>(cj.add(4 * v), mask, last, x);
                }
            }
        }
    }
}

/// Four values at p, or only `mask`'s lanes (the others 0) when MASKED and this is the last
/// vector of a tile.
#[inline(always)]
unsafe fn load<const MASKED: bool>(p: *const f64, mask: __m256i, last: bool) -> __m256d {
    // SAFETY: the caller's tile bounds.
    unsafe {
        if MASKED && last {
            _mm256_maskload_pd(p, mask)
        } else {
            _mm256_loadu_pd(p)
        }
    }
}

#[inline(always)]
unsafe fn store<const MASKED: bool>(p: *mut f64, mask: __m256i, last: bool, x: __m256d) {
    // SAFETY: the caller's tile bounds.
    unsafe {
        if MASKED && last {
            _mm256_maskstore_pd(p, mask, x)
        } else {
            _mm256_storeu_pd(p, x)
        }
    }
}

#[inline(always)]
fn full_mask() -> __m256i {
    tail_mask(4)
}

/// The first `r` of four lanes (1 ≤ r ≤ 4).
#[inline(always)]
fn tail_mask(r: usize) -> __m256i {
    let lane = |l: usize| if l < r { -1i64 } else { 0 };
    // SAFETY: AVX, implied by the AVX2 of every caller.
    unsafe { _mm256_setr_epi64x(lane(0), lane(1), lane(2), lane(3)) }
}

#[cfg(test)]
mod tests {
    use crate::linalg::gemm_columns;
    use nalgebra::DMatrix;

    /// Every tile shape (rows 1..=13 cover full, 4-row and masked 1..3-row tails; columns
    /// 0..=9 the 4-column tiles and the 1..3-column rests) against nalgebra's own product, with
    /// β = 0 over a C full of NaN (never read), β = 1 and a general β; and the columns beyond
    /// `ncols`, and rows beyond a masked tail's, untouched.
    #[test]
    fn equals_nalgebra_product_on_every_tile_shape() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let mut worst = 0.0f64;
        for m in 1..=13 {
            for k in 0..=9 {
                for n in 0..=9 {
                    let a = DMatrix::from_fn(m, k, |_, _| next());
                    let b = DMatrix::from_fn(k, n + 1, |_, _| next());
                    for (alpha, beta) in [(1.0, 0.0), (-0.7, 1.0), (1.3, -0.4)] {
                        let c0 = DMatrix::from_fn(m, n + 1, |_, _| next());
                        let mut c = if beta == 0.0 {
                            DMatrix::from_element(m, n + 1, f64::NAN)
                        } else {
                            c0.clone()
                        };
                        let last = c.column(n).clone_owned();
                        gemm_columns(&mut c, alpha, &a, &b, beta, n);
                        let want = (&a * b.columns(0, n)) * alpha + c0.columns(0, n) * beta;
                        for j in 0..n {
                            for i in 0..m {
                                let scale = 1.0 + want[(i, j)].abs() + k as f64;
                                worst = worst.max((c[(i, j)] - want[(i, j)]).abs() / scale);
                            }
                        }
                        assert!(
                            c.column(n)
                                .iter()
                                .zip(last.iter())
                                .all(|(x, y)| x.to_bits() == y.to_bits()),
                            "{m}×{k}·{n}: a column beyond ncols was written"
                        );
                    }
                }
            }
        }
        // Rounding of sums of ≤ 9 products of numbers ≤ 1: 1.3e-16 measured.
        assert!(
            worst < 2.0 * f64::EPSILON,
            "worst relative difference {worst:.2e}"
        );
    }
}
