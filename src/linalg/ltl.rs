//! Featherstone's LTL factorization of the joint-space inertia matrix, `M = Lᵀ L`, exploiting
//! branch-induced sparsity: `L[k, i] ≠ 0` only when velocity coordinate i is k itself or an
//! ancestor of k (`parent[k]` is the previous coordinate on the path to the root, `usize::MAX`
//! at the root). Solves with L and Lᵀ then cost O(depth) per coordinate, and a right side that
//! lives on one branch (a foot's Jacobian row) stays on that branch.

use super::dense::dot_unrolled;
use nalgebra::DMatrix;

/// `parent[k]` of a coordinate at the root (no ancestor).
pub const NO_PARENT: usize = usize::MAX;

/// In place: the lower triangle of `m` becomes L with M = Lᵀ L, and `inv_diag` (n) the
/// reciprocals of L's diagonal, which the solves multiply by: a division's latency on the chain
/// of dependent updates cost 16 % of Solo12's constrained dynamics. Fails with the coordinate
/// whose pivot is ≤ `rel_tol · max diag(M)` (M not positive definite).
///
/// Left-looking, from the leaves: with `desc(k)` the coordinates below k, one contiguous range
/// `k+1..subtree_end[k]` under depth-first numbering,
///   `L[k,k]² = M[k,k] − Σ_{d∈desc(k)} L[d,k]²`,
///   `L[k,i] = (M[k,i] − Σ_{d∈desc(k)} L[d,k] L[d,i]) / L[k,k]` for i an ancestor of k:
/// every sum a dot product of two contiguous column segments, the tree walked only over the
/// ancestors (the right-looking form walked it in its inner loop: 25 instructions per
/// multiply-add on talos_reduced).
pub fn ltl_factor(
    m: &mut DMatrix<f64>,
    parent: &[usize],
    subtree_end: &[usize],
    rel_tol: f64,
    inv_diag: &mut [f64],
) -> Result<(), usize> {
    let n = m.nrows();
    // Column-major storage, entry (r, c) at c·n + r.
    let a = m.as_mut_slice();
    let scale = (0..n)
        .map(|i| a[i * n + i].abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    for k in (0..n).rev() {
        let below = k + 1..subtree_end[k];
        // Column c's rows below k.
        let rows = |c: usize| (c * n + below.start, c * n + below.end);
        let (s, e) = rows(k);
        let dkk = a[k * n + k] - dot_unrolled(&a[s..e], &a[s..e]);
        if dkk.is_nan() || dkk <= rel_tol * scale {
            return Err(k);
        }
        let d = dkk.sqrt();
        let r = 1.0 / d;
        a[k * n + k] = d;
        inv_diag[k] = r;
        let mut i = parent[k];
        while i != NO_PARENT {
            let (si, ei) = rows(i);
            let x = a[i * n + k] - dot_unrolled(&a[s..e], &a[si..ei]);
            a[i * n + k] = x * r;
            i = parent[i];
        }
    }
    Ok(())
}

/// Solve `Lᵀ y = x` in place (x → y): leaves first, each result scattered to its ancestors.
pub fn ltl_solve_lt(l: &DMatrix<f64>, inv_diag: &[f64], parent: &[usize], x: &mut [f64]) {
    let n = l.nrows();
    let a = l.as_slice();
    for k in (0..x.len()).rev() {
        if x[k] == 0.0 {
            continue;
        }
        let y = x[k] * inv_diag[k];
        x[k] = y;
        let mut i = parent[k];
        while i != NO_PARENT {
            x[i] -= a[i * n + k] * y;
            i = parent[i];
        }
    }
}

/// Solve `L z = y` in place: root first, each row gathering from its ancestors.
pub fn ltl_solve_l(l: &DMatrix<f64>, inv_diag: &[f64], parent: &[usize], y: &mut [f64]) {
    let n = l.nrows();
    let a = l.as_slice();
    for k in 0..y.len() {
        let mut s = y[k];
        let mut i = parent[k];
        while i != NO_PARENT {
            s -= a[i * n + k] * y[i];
            i = parent[i];
        }
        y[k] = s * inv_diag[k];
    }
}
