//! LU with partial pivoting in place (the implicit integrators' matrices, the embedded form's
//! dependent block). Column-oriented on nalgebra's column-major storage: every inner loop runs
//! down a contiguous column.

use nalgebra::DMatrix;

/// LU with partial pivoting in place, `P A = L U` (unit L below the diagonal, U on and above it),
/// `piv[k]` the row swapped with k at step k. Acts on the leading n × n block, n = `piv.len()`
/// (one workspace serves systems of varying size). False when a pivot is zero or not finite.
pub fn lu_in_place(a: &mut DMatrix<f64>, piv: &mut [usize]) -> bool {
    let n = piv.len();
    let ld = a.nrows();
    let s = a.as_mut_slice();
    for k in 0..n {
        let col = &s[k * ld..k * ld + n];
        let (mut p, mut best) = (k, col[k].abs());
        for (r, x) in col.iter().enumerate().skip(k + 1) {
            if x.abs() > best {
                (p, best) = (r, x.abs());
            }
        }
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        piv[k] = p;
        if p != k {
            for c in 0..n {
                s.swap(c * ld + p, c * ld + k);
            }
        }
        let (left, right) = s.split_at_mut((k + 1) * ld);
        let lk = &mut left[k * ld + k..k * ld + n];
        let d = lk[0];
        for l in &mut lk[1..] {
            *l /= d;
        }
        let lk = &lk[1..];
        for c in k + 1..n {
            let col = &mut right[(c - k - 1) * ld..(c - k - 1) * ld + n];
            let akc = col[k];
            // A zero above the pivot skips its column (the structured matrices' blocks); the
            // inner loop itself is a branch-free axpy.
            if akc != 0.0 {
                for (x, &l) in col[k + 1..].iter_mut().zip(lk) {
                    *x -= l * akc;
                }
            }
        }
    }
    true
}

/// Solve `A x = b` in place with the factor of [`lu_in_place`] (n = `piv.len()`).
pub fn lu_solve(lu: &DMatrix<f64>, piv: &[usize], b: &mut [f64]) {
    let n = piv.len();
    let ld = lu.nrows();
    let s = lu.as_slice();
    for k in 0..n {
        b.swap(k, piv[k]);
    }
    // L y = P b, then U x = y, each column of the factor once.
    for k in 0..n {
        let bk = b[k];
        if bk != 0.0 {
            for (x, &l) in b[k + 1..n].iter_mut().zip(&s[k * ld + k + 1..k * ld + n]) {
                *x -= l * bk;
            }
        }
    }
    for k in (0..n).rev() {
        b[k] /= s[k * ld + k];
        let bk = b[k];
        if bk != 0.0 {
            for (x, &u) in b[..k].iter_mut().zip(&s[k * ld..k * ld + k]) {
                *x -= u * bk;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ‖A x − b‖ on a matrix that needs pivoting (a zero leading entry), inside a larger
    /// workspace (leading 4 × 4 block of a 6 × 6).
    #[test]
    fn solves_with_pivoting_in_a_larger_workspace() {
        let a4 = [
            [0.0, 2.0, -1.0, 3.0],
            [4.0, 1.0, 0.5, -2.0],
            [1.0, -3.0, 2.0, 1.0],
            [-2.0, 0.0, 1.0, 5.0],
        ];
        let mut a = DMatrix::from_element(6, 6, 7.0);
        for r in 0..4 {
            for c in 0..4 {
                a[(r, c)] = a4[r][c];
            }
        }
        let b = [1.0, -2.0, 0.5, 3.0];
        let mut piv = [0; 4];
        assert!(lu_in_place(&mut a, &mut piv));
        let mut x = b;
        lu_solve(&a, &piv, &mut x);
        for r in 0..4 {
            let ax: f64 = (0..4).map(|c| a4[r][c] * x[c]).sum();
            assert!((ax - b[r]).abs() < 1e-14, "row {r}: {ax} against {}", b[r]);
        }
        let mut singular = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        assert!(!lu_in_place(&mut singular, &mut [0; 2]));
    }
}
