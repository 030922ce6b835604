//! Featherstone's LTL factorization of the joint-space inertia matrix, `M = Lᵀ L`, exploiting
//! branch-induced sparsity: `L[k, i] ≠ 0` only when velocity coordinate i is k itself or an
//! ancestor of k (`parent[k]` is the previous coordinate on the path to the root, `usize::MAX`
//! at the root). Solves with L and Lᵀ then cost O(depth) per coordinate, and a right side that
//! lives on one branch (a foot's Jacobian row) stays on that branch.

use nalgebra::DMatrix;

/// `parent[k]` of a coordinate at the root (no ancestor).
pub const NO_PARENT: usize = usize::MAX;

/// In place: the lower triangle of `m` becomes L with M = Lᵀ L. Fails with the coordinate whose
/// pivot is ≤ `rel_tol · max diag(M)` (M not positive definite).
pub fn ltl_factor(m: &mut DMatrix<f64>, parent: &[usize], rel_tol: f64) -> Result<(), usize> {
    let n = m.nrows();
    // Column-major storage, entry (r, c) at c·n + r: flat indexing skips nalgebra's two-index
    // bounds checks in these O(n·depth²) loops.
    let a = m.as_mut_slice();
    let scale = (0..n)
        .map(|i| a[i * n + i].abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    for k in (0..n).rev() {
        let dkk = a[k * n + k];
        if dkk.is_nan() || dkk <= rel_tol * scale {
            return Err(k);
        }
        let d = dkk.sqrt();
        a[k * n + k] = d;
        let mut i = parent[k];
        while i != NO_PARENT {
            a[i * n + k] /= d;
            i = parent[i];
        }
        let mut i = parent[k];
        while i != NO_PARENT {
            let lki = a[i * n + k];
            let mut j = i;
            while j != NO_PARENT {
                a[j * n + i] -= lki * a[j * n + k];
                j = parent[j];
            }
            i = parent[i];
        }
    }
    Ok(())
}

/// Solve `Lᵀ y = x` in place (x → y): leaves first, each result scattered to its ancestors.
pub fn ltl_solve_lt(l: &DMatrix<f64>, parent: &[usize], x: &mut [f64]) {
    let n = l.nrows();
    let a = l.as_slice();
    for k in (0..x.len()).rev() {
        if x[k] == 0.0 {
            continue;
        }
        let y = x[k] / a[k * n + k];
        x[k] = y;
        let mut i = parent[k];
        while i != NO_PARENT {
            x[i] -= a[i * n + k] * y;
            i = parent[i];
        }
    }
}

/// Solve `L z = y` in place: root first, each row gathering from its ancestors.
pub fn ltl_solve_l(l: &DMatrix<f64>, parent: &[usize], y: &mut [f64]) {
    let n = l.nrows();
    let a = l.as_slice();
    for k in 0..y.len() {
        let mut s = y[k];
        let mut i = parent[k];
        while i != NO_PARENT {
            s -= a[i * n + k] * y[i];
            i = parent[i];
        }
        y[k] = s / a[k * n + k];
    }
}
