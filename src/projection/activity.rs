//! Which inequality rows a velocity counts as meeting: the primal tolerance of a row, relative
//! to the problem's own velocity scale, and the active set it gives.

use super::problem::{Bounds, ProjectionProblem};
use super::qp::IneqRow;
use nalgebra::DMatrix;

/// Primal tolerance on a row `c v ≤ d` (physical units), relative to the row's terms and to the
/// problem's velocity scale `vscale` (so a request in mm/s is treated like one in m/s).
pub(super) fn row_tol(
    row: IneqRow,
    bounds: &Bounds,
    a: &DMatrix<f64>,
    b: &[f64],
    v: &[f64],
    vscale: f64,
) -> f64 {
    let scale = match row {
        IneqRow::Bound(..) => row.value(bounds, b).abs() + vscale,
        IneqRow::User(k) => {
            b[k].abs()
                + (0..v.len())
                    .map(|c| a[(k, c)].abs() * (v[c].abs() + vscale))
                    .sum::<f64>()
        }
    };
    1e-9 * scale
}

/// Velocity scale of a problem: the largest of |v_des|, the finite bounds and |b_k| / max|a_k|.
pub(super) fn velocity_scale(p: &ProjectionProblem, bounds: &Bounds) -> f64 {
    let mut s = p.v_des.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for x in bounds.lo.iter().chain(&bounds.hi) {
        if x.is_finite() {
            s = s.max(x.abs());
        }
    }
    for k in 0..p.a.nrows() {
        let amax = p.a.row(k).amax();
        if amax > 0.0 {
            s = s.max(p.b[k].abs() / amax);
        }
    }
    s.max(f64::MIN_POSITIVE)
}

/// Active = rows in the working set or met with equality (within tolerance) at v.
pub(super) fn mark_active(
    ineq: &[IneqRow],
    working: &[usize],
    bounds: &Bounds,
    p: &ProjectionProblem,
    v: &[f64],
    vscale: f64,
    active: &mut Vec<usize>,
) {
    active.clear();
    for (t, &r) in ineq.iter().enumerate() {
        let viol = r.violation(v, bounds, &p.a, &p.b);
        if viol.abs() <= row_tol(r, bounds, &p.a, &p.b, v, vscale) || working.contains(&t) {
            active.push(t);
        }
    }
}
