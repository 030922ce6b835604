//! The embedded form's coordinate partition: which rows of J are kept (independent rows) and
//! which velocities are dependent (v_d = B v_i), chosen from J at the current state by
//! column-pivoted QR, allocation-free on a reusable [`PartitionWorkspace`].

use crate::algorithm::DENSE_EAGER_NV;
use crate::linalg::ColumnPivotedQr;
use nalgebra::DMatrix;

/// Relative QR pivot below which a row or column of J counts as dependent.
const TOL: f64 = 1e-10;

/// The coordinate partition chosen from J: independent and dependent velocity indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Partition {
    /// Independent velocity indices (v_i), ascending.
    pub independent: Vec<usize>,
    /// Dependent velocity indices (v_d = B v_i), ascending.
    pub dependent: Vec<usize>,
    /// Rows of J kept (independent rows), ascending.
    pub rows: Vec<usize>,
}

/// Buffers of the partition choice (grown to the largest J seen, then reused).
#[derive(Clone, Debug, Default)]
pub struct PartitionWorkspace {
    qr: ColumnPivotedQr,
    selected: Vec<usize>,
    others: Vec<usize>,
    /// Orthonormal basis of the preferred dependent columns of J_r, and the other columns with
    /// their part in that span removed.
    u: DMatrix<f64>,
    rest: DMatrix<f64>,
}

impl PartitionWorkspace {
    /// Buffers for J of nc × nv.
    pub fn new(nc: usize, nv: usize) -> Self {
        let n = nc.max(nv);
        Self {
            // A large model's QR is sized by its first use.
            qr: if n > DENSE_EAGER_NV {
                ColumnPivotedQr::default()
            } else {
                ColumnPivotedQr::new(n, n)
            },
            selected: Vec::with_capacity(n),
            others: Vec::with_capacity(nv),
            u: DMatrix::zeros(nc, nv),
            rest: DMatrix::zeros(nc, nv),
        }
    }
}

/// Choose the partition at the current J (allocates its result; the dynamics use
/// [`partition_into`]).
pub fn partition(j: &DMatrix<f64>) -> Partition {
    partition_preferring(j, &[])
}

/// [`partition`] taking the `preferred` velocity columns as dependent first (allocates its result).
pub fn partition_preferring(j: &DMatrix<f64>, preferred: &[usize]) -> Partition {
    let mut p = Partition::default();
    let mut ws = PartitionWorkspace::new(j.nrows(), j.ncols());
    partition_into(j, preferred, &mut ws, &mut p);
    p
}

/// Choose the partition at the current J into `p`, taking the `preferred` velocity columns (the
/// scene's `dependent:`) as dependent first where they are independent, and completing with the
/// best-conditioned of the others (column-pivoted QR of their part outside the span of the
/// preferred columns). Allocation-free once `ws` and `p` have held a partition of this size.
pub fn partition_into(
    j: &DMatrix<f64>,
    preferred: &[usize],
    ws: &mut PartitionWorkspace,
    p: &mut Partition,
) {
    let (nc, nv) = j.shape();
    // Independent rows of J: independent columns of Jᵀ.
    ws.qr
        .independent_columns(nv, nc, |i, k| j[(k, i)], TOL, &mut p.rows);
    let nr = p.rows.len();
    let rows = &p.rows;
    p.dependent.clear();
    if !preferred.is_empty() {
        ws.qr.independent_columns(
            nr,
            preferred.len(),
            |a, b| j[(rows[a], preferred[b])],
            TOL,
            &mut ws.selected,
        );
        p.dependent
            .extend(ws.selected.iter().map(|&k| preferred[k]));
    }
    if p.dependent.len() < nr {
        ws.others.clear();
        ws.others
            .extend((0..nv).filter(|c| !p.dependent.contains(c)));
        let (nd, no) = (p.dependent.len(), ws.others.len());
        // Grown when too small (`<=` would only reallocate more often: an equivalent mutation).
        if ws.u.nrows() < nr || ws.u.ncols() < nv {
            ws.u = DMatrix::zeros(nr.max(nc), nv);
            ws.rest = DMatrix::zeros(nr.max(nc), nv);
        }
        // u: Gram–Schmidt (twice, for orthogonality to rounding) on the preferred columns.
        for b in 0..nd {
            for a in 0..nr {
                ws.u[(a, b)] = j[(rows[a], p.dependent[b])];
            }
            for _ in 0..2 {
                for c in 0..b {
                    let d: f64 = (0..nr).map(|a| ws.u[(a, c)] * ws.u[(a, b)]).sum();
                    for a in 0..nr {
                        ws.u[(a, b)] -= d * ws.u[(a, c)];
                    }
                }
            }
            let norm = (0..nr).map(|a| ws.u[(a, b)].powi(2)).sum::<f64>().sqrt();
            for a in 0..nr {
                ws.u[(a, b)] /= norm;
            }
        }
        for (c, &col) in ws.others.iter().enumerate() {
            for a in 0..nr {
                ws.rest[(a, c)] = j[(rows[a], col)];
            }
            for b in 0..nd {
                let d: f64 = (0..nr).map(|a| ws.u[(a, b)] * ws.rest[(a, c)]).sum();
                for a in 0..nr {
                    ws.rest[(a, c)] -= d * ws.u[(a, b)];
                }
            }
        }
        let rest = &ws.rest;
        ws.qr
            .independent_columns(nr, no, |a, c| rest[(a, c)], TOL, &mut ws.selected);
        let need = nr - nd;
        let others = &ws.others;
        p.dependent
            .extend(ws.selected.iter().take(need).map(|&k| others[k]));
    }
    // sort_unstable: no buffer (a stable sort may allocate one).
    p.dependent.sort_unstable();
    p.rows.sort_unstable();
    p.independent.clear();
    let dep = &p.dependent;
    p.independent.extend((0..nv).filter(|c| !dep.contains(c)));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two rows, the first column preferred. The others' parts outside its span are (0, 0.1)
    /// and (0, 0.5): the second completes the dependent set although the first column is
    /// the longer (‖(1, 0.1)‖ > 0.5), because only the part outside the preferred span counts.
    #[test]
    fn the_completion_is_judged_outside_the_preferred_span() {
        let j = DMatrix::from_row_slice(2, 3, &[1.0, 1.0, 0.0, 0.0, 0.1, 0.5]);
        let p = partition_preferring(&j, &[0]);
        let mut dependent = p.dependent.clone();
        dependent.sort_unstable();
        assert_eq!(dependent, [0, 2]);
        assert_eq!(p.independent, [1]);
    }
}
