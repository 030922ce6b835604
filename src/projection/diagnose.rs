//! Diagnosis of an infeasible projection: which constraints, bounds and inequalities cannot hold
//! together.
//!
//! Clarabel's primal-infeasibility certificate is a dual ray z with `Ãᵀ z = 0`, `b̃ᵀ z < 0`
//! (z ≥ 0 on inequality rows): the rows where z ≠ 0 already form a conflicting set (Farkas).
//! A deletion filter then makes it minimal: each row of the set is dropped in turn and kept out
//! if the remaining rows are still infeasible, so every row reported is necessary (an
//! irreducible infeasible subsystem; dropping any one of them restores feasibility). This runs
//! only on infeasible requests and allocates freely.

use super::problem::Side;
use super::qp::{IneqRow, QpCache, QpData, feasible};
use serde::Serialize;

/// One member of a conflicting set, by index (named by the report).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Conflict {
    /// Row r of the stacked constraint Jacobian.
    ConstraintRow(usize),
    /// The bound on velocity coordinate `index`.
    Bound {
        /// Index of the velocity coordinate (0..nv).
        index: usize,
        /// Which of its bounds.
        side: Side,
    },
    /// Row k of the user inequalities A v ≤ b.
    Inequality(usize),
}

/// A minimal conflicting set from the certificate of the last (primal-infeasible) solve.
pub(super) fn diagnose(data: &QpData, qp: &QpCache, ineq: &[IneqRow]) -> Vec<Conflict> {
    let nv = data.m.nrows();
    let nc = qp.nc();
    let n_rows = nc + ineq.len();
    let infeasible = |set: &[usize]| -> Option<bool> {
        let (mut eq, mut le) = (vec![], vec![]);
        for &k in set {
            let row = qp.scaled_row(k, nv, data);
            if k < nc { eq.push(row) } else { le.push(row) }
        }
        feasible(nv, &eq, &le).map(|f| !f)
    };
    let mut set = qp.certificate_support(1e-7);
    if infeasible(&set) != Some(true) {
        set = (0..n_rows).collect();
    }
    let candidates = set.clone();
    for k in candidates {
        let trial: Vec<usize> = set.iter().copied().filter(|&x| x != k).collect();
        if infeasible(&trial) == Some(true) {
            set = trial;
        }
    }
    set.iter()
        .map(|&k| {
            if k < nc {
                Conflict::ConstraintRow(k)
            } else {
                match ineq[k - nc] {
                    IneqRow::Bound(index, side) => Conflict::Bound { index, side },
                    IneqRow::User(u) => Conflict::Inequality(u),
                }
            }
        })
        .collect()
}
