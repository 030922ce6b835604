//! LU with partial pivoting in place (the implicit integrator's Newton matrix).

use nalgebra::DMatrix;

/// LU with partial pivoting in place, `P A = L U` (unit L below the diagonal, U on and above it),
/// `piv[k]` the row swapped with k at step k. Acts on the leading n × n block, n = `piv.len()`
/// (one workspace serves systems of varying size). False when a pivot is zero or not finite.
pub fn lu_in_place(a: &mut DMatrix<f64>, piv: &mut [usize]) -> bool {
    let n = piv.len();
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
            for c in 0..n {
                a.swap((p, c), (k, c));
            }
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

/// Solve `A x = b` in place with the factor of [`lu_in_place`] (n = `piv.len()`).
pub fn lu_solve(lu: &DMatrix<f64>, piv: &[usize], b: &mut [f64]) {
    let n = piv.len();
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
