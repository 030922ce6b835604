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
/// ancestors (a right-looking form walks it in its inner loop: 25 instructions per
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

wide_fn! {
/// Solve `Lᵀ Y = X` in place for w right sides at once, X stored by rows (row k, the w entries of
/// coordinate k, at `x[k·w..(k+1)·w]`: the layout of a column-major w × n J, so `X = Jᵀ` is J's
/// storage). Each column gets the operations of [`ltl_solve_lt`] in the same order (a zero
/// entry, skipped there, subtracts an exact zero here), but the walk up the tree — a chain of
/// dependent loads — is taken once per coordinate instead of once per column, each step a
/// contiguous run of w updates. (Four columns at a time through the walk, or explicit runs of
/// four, took more instructions on solo12: the compiler fuses the runs into a 16-wide body.)
pub fn ltl_solve_lt_rows(
    l: &DMatrix<f64>,
    inv_diag: &[f64],
    parent: &[usize],
    x: &mut [f64],
    w: usize,
) {
    let n = l.nrows();
    let a = l.as_slice();
    for k in (0..x.len() / w).rev() {
        // Ancestors come first in depth-first order: every row i < k is in `head`.
        let (head, tail) = x.split_at_mut(k * w);
        let row = &mut tail[..w];
        if row.iter().all(|&y| y == 0.0) {
            continue; // a coordinate no row reaches (an arm under foot contacts)
        }
        let d = inv_diag[k];
        row.iter_mut().for_each(|y| *y *= d);
        let mut i = parent[k];
        while i != NO_PARENT {
            let lki = a[i * n + k];
            for (xi, &y) in head[i * w..(i + 1) * w].iter_mut().zip(row.iter()) {
                *xi -= lki * y;
            }
            i = parent[i];
        }
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

/// M⁻¹ into the leading n × n block of `out` (both triangles) from M's LTL factor (`l`,
/// `inv_diag`), through W = L⁻¹ in the leading block of `w`: M⁻¹ = L⁻¹ L⁻ᵀ = Σ_i w_i w_iᵀ over
/// W's columns. L⁻¹ keeps L's tree sparsity, so column i of W lives on i's subtree — one
/// contiguous range — and each term is a rank-1 update of that range's block: on
/// talos_reduced ≈ 5 000 multiply-adds, against n³/2 ≈ 27 000 for a dense factor, inverse and
/// product.
pub fn ltl_inverse(
    l: &DMatrix<f64>,
    inv_diag: &[f64],
    parent: &[usize],
    subtree_end: &[usize],
    w: &mut DMatrix<f64>,
    out: &mut DMatrix<f64>,
) {
    let n = l.nrows();
    let (la, ldw, ldo) = (l.as_slice(), w.nrows(), out.nrows());
    let wa = w.as_mut_slice();
    // Column i of W solves L w = e_i, root first: for k below i,
    // W[k,i] = −W[k,k] Σ_{d ancestor of k, d ≥ i} L[k,d] W[d,i].
    for i in 0..n {
        let col = &mut wa[i * ldw..i * ldw + n];
        col[i] = inv_diag[i];
        for k in i + 1..subtree_end[i] {
            let mut s = 0.0;
            let mut d = parent[k];
            while d != NO_PARENT && d >= i {
                s += la[d * n + k] * col[d];
                d = parent[d];
            }
            col[k] = -inv_diag[k] * s;
        }
    }
    let oa = out.as_mut_slice();
    for c in 0..n {
        oa[c * ldo + c..c * ldo + n].fill(0.0);
    }
    // The lower triangle, one rank-1 update per column of W.
    for i in 0..n {
        let seg = &wa[i * ldw + i..i * ldw + subtree_end[i]];
        for (c, &x) in seg.iter().enumerate() {
            let col = i + c;
            let dst = &mut oa[col * ldo + col..col * ldo + subtree_end[i]];
            for (o, &y) in dst.iter_mut().zip(&seg[c..]) {
                *o += x * y;
            }
        }
    }
    for c in 1..n {
        for r in 0..c {
            oa[c * ldo + r] = oa[r * ldo + c];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A branched tree in depth-first order: 0 ← 1 ← 2, then two branches under 2 (3 ← 4 and
    /// 5 ← 6 ← 7) and one under the root (8).
    const PARENT: [usize; 9] = [NO_PARENT, 0, 1, 2, 3, 2, 5, 6, 0];

    fn is_ancestor_or_self(i: usize, mut k: usize) -> bool {
        while k != NO_PARENT {
            if k == i {
                return true;
            }
            k = PARENT[k];
        }
        false
    }

    /// A fixed pseudo-random sequence in [−1, 1).
    fn uniform(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// L₀ with the tree's sparsity and a positive diagonal, M = L₀ᵀ L₀: the factor must give
    /// L₀ back, and the many-column solve must give each column of the one-column solve to
    /// the bit and meet Lᵀ Y = X, with rows of X that are zero (coordinates no row reaches).
    #[test]
    fn many_column_solve_equals_the_single_solves_and_inverts_lt() {
        let n = PARENT.len();
        let mut seed = 7;
        let mut l0 = DMatrix::<f64>::zeros(n, n);
        for k in 0..n {
            for i in 0..=k {
                if is_ancestor_or_self(i, k) {
                    l0[(k, i)] = if i == k {
                        1.5 + uniform(&mut seed)
                    } else {
                        uniform(&mut seed)
                    };
                }
            }
        }
        let subtree_end: Vec<usize> = (0..n)
            .map(|k| {
                (k + 1..n)
                    .find(|&j| !is_ancestor_or_self(k, j))
                    .unwrap_or(n)
            })
            .collect();
        let mut l = l0.transpose() * &l0;
        let mut inv_diag = vec![0.0; n];
        ltl_factor(&mut l, &PARENT, &subtree_end, 1e-14, &mut inv_diag).expect("SPD");
        for k in 0..n {
            for i in 0..=k {
                // Achieved 5.6e-16.
                assert!((l[(k, i)] - l0[(k, i)]).abs() < 2e-15, "L[{k},{i}]");
            }
        }
        let w = 5;
        let mut x: Vec<f64> = (0..n * w).map(|_| uniform(&mut seed)).collect();
        x[4 * w..5 * w].fill(0.0);
        x[8 * w..9 * w].fill(0.0);
        let mut y = x.clone();
        ltl_solve_lt_rows(&l, &inv_diag, &PARENT, &mut y, w);
        for c in 0..w {
            let mut col: Vec<f64> = (0..n).map(|k| x[k * w + c]).collect();
            ltl_solve_lt(&l, &inv_diag, &PARENT, &mut col);
            for k in 0..n {
                assert_eq!(y[k * w + c].to_bits(), col[k].to_bits(), "Y[{k},{c}]");
            }
            // Lᵀ y = x with the L₀ the factor came from.
            for i in 0..n {
                let lty: f64 = (i..n).map(|k| l0[(k, i)] * y[k * w + c]).sum();
                // Achieved 2.1e-15 (|Y| up to a few units).
                assert!((lty - x[i * w + c]).abs() < 5e-15, "(Lᵀ Y)[{i},{c}]: {lty}");
            }
        }
    }
}
