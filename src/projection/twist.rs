//! Planner semantics for a twist request (`mode: twist`, the default when a request gives
//! `base_twist`): what a base controller between a planner and the wheels is expected to do.
//!
//! 1. The nearest velocity the constraints allow *in the requested components themselves*
//!    (base twist and named joints, SI units, unit weights), the other coordinates taking the
//!    least kinetic energy among those:
//!    `v_eq = N z`, `z = argmin ‖S_T N z − u_T‖²` then `argmin zᵀ(NᵀMN)z`, with N a basis of
//!    null(J) and S_T the selection of the requested coordinates. A sideways twist for a
//!    differential drive therefore gives zero base motion.
//! 2. One scale s ∈ [0, 1], the largest that satisfies every bound (`lo ≤ s v_eq ≤ hi`,
//!    `A s v_eq ≤ b`): the command keeps its direction and the path its curvature, as a
//!    diff-drive controller saturating its wheels does.
//!
//! When zero velocity itself violates a bound (a request that forces motion), no scale exists
//! and the request is solved in the mass metric instead (the caller falls back).

use super::problem::Bounds;
use nalgebra::{DMatrix, DVector};

/// `v_eq` of step 1, or None when M restricted to null(J) is singular.
pub fn nearest_in_task(
    m: &DMatrix<f64>,
    j: &DMatrix<f64>,
    given: &[bool],
    u: &[f64],
) -> Option<DVector<f64>> {
    let nv = m.nrows();
    let n = if j.nrows() == 0 {
        DMatrix::identity(nv, nv)
    } else {
        // Full SVD of the square, zero-padded [Jᵀ 0] (nv × nv): the left singular vectors with
        // zero singular value span null(J).
        let mut jt = DMatrix::zeros(nv, nv.max(j.nrows()));
        jt.view_mut((0, 0), (nv, j.nrows()))
            .copy_from(&j.transpose());
        let svd = jt.svd(true, false);
        let u_full = svd.u?;
        let smax = svd.singular_values.amax().max(f64::MIN_POSITIVE);
        let cols: Vec<usize> = (0..nv)
            .filter(|&c| svd.singular_values[c] <= 1e-10 * smax)
            .collect();
        u_full.select_columns(cols.iter())
    };
    if n.ncols() == 0 {
        return Some(DVector::zeros(nv));
    }
    let t: Vec<usize> = (0..nv).filter(|&i| given[i]).collect();
    let a = n.select_rows(t.iter());
    let ut = DVector::from_fn(t.len(), |k, _| u[t[k]]);
    let g = n.transpose() * m * &n;
    let l = g.cholesky()?.l();
    // A L⁻ᵀ: solve L X = Aᵀ, then transpose.
    let x = l.solve_lower_triangular(&a.transpose())?;
    let al = x.transpose();
    let svd = al.svd(true, true);
    let smax = svd.singular_values.amax();
    let y = if smax > 0.0 {
        svd.solve(&ut, 1e-12 * smax).ok()?
    } else {
        DVector::zeros(n.ncols())
    };
    let z = l.transpose().solve_upper_triangular(&y)?;
    Some(n * z)
}

/// The largest s ∈ [0, 1] with `lo ≤ s v ≤ hi` and `A s v ≤ b`, or None when s = 0 already
/// violates a bound.
pub fn largest_feasible_scale(
    v: &[f64],
    bounds: &Bounds,
    a: &DMatrix<f64>,
    b: &[f64],
) -> Option<f64> {
    let mut s: f64 = 1.0;
    for (i, &x) in v.iter().enumerate() {
        let (lo, hi) = (bounds.lo[i], bounds.hi[i]);
        if lo > 0.0 || hi < 0.0 {
            return None;
        }
        if x > hi {
            s = s.min(hi / x);
        } else if x < lo {
            s = s.min(lo / x);
        }
    }
    for k in 0..a.nrows() {
        if b[k] < 0.0 {
            return None;
        }
        let y: f64 = (0..v.len()).map(|c| a[(k, c)] * v[c]).sum();
        if y > b[k] {
            s = s.min(b[k] / y);
        }
    }
    Some(s.max(0.0))
}
