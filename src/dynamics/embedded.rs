//! The multiplier-free (embedded) form, after Voronets: the constraints `J v = 0` are solved for
//! dependent velocities, `v_d = B v_i` with `B = −J_d⁻¹ J_i`, so `v = N v_i`, `N = P [I; B]`
//! (P the column permutation), and the accelerations `q̈ = N q̈_i + q̈_p` with
//! `q̈_p = P [0; J_d⁻¹ b]`, b = −γ − K_d J v − K_p φ. Projecting the dynamics on N removes the
//! multipliers (Nᵀ Jᵀ = 0):
//!   (Nᵀ M N) q̈_i = Nᵀ (τ − h − M q̈_p),
//! nv − rank(J) equations instead of nv + nc. Redundant rows are dropped first (row-pivoted QR);
//! the dependent columns are the best-conditioned ones (column-pivoted QR). This path allocates:
//! it serves when nobody asks for constraint forces, not in the allocation-free loop.

use super::Baumgarte;
use crate::algorithm::{Data, crba, nonlinear_effects};
use crate::constraints::{ConstraintData, ConstraintSet};
use crate::error::{Error, Result};
use crate::linalg::independent_columns;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// The coordinate partition chosen from J: independent and dependent velocity indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Partition {
    /// Independent velocity indices (v_i).
    pub independent: Vec<usize>,
    /// Dependent velocity indices (v_d = B v_i).
    pub dependent: Vec<usize>,
    /// Rows of J kept (independent rows).
    pub rows: Vec<usize>,
}

/// Workspace of the embedded form.
#[derive(Clone, Debug, Default)]
pub struct EmbeddedWorkspace {
    /// The partition used at the last solve.
    pub partition: Partition,
    /// N (nv × (nv − r)).
    pub n: DMatrix<f64>,
    /// q̈ (nv).
    pub qdd: DVector<f64>,
}

/// Choose the partition at the current J.
pub fn partition(j: &DMatrix<f64>) -> Partition {
    let nv = j.ncols();
    let rows = independent_columns(&j.transpose(), 1e-10);
    let jr = j.select_rows(rows.iter());
    let mut dependent = independent_columns(&jr, 1e-10);
    dependent.sort();
    let independent = (0..nv).filter(|c| !dependent.contains(c)).collect();
    let mut rows = rows;
    rows.sort();
    Partition {
        independent,
        dependent,
        rows,
    }
}

/// q̈ of the constrained system without multipliers (into `ws.qdd`); `ws.partition` is chosen
/// afresh unless `keep_partition` and it still has the right rank.
#[allow(clippy::too_many_arguments)]
pub fn embedded_forward_dynamics(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    ws: &mut EmbeddedWorkspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    stab: Baumgarte,
) -> Result<()> {
    set.evaluate(model, data, cd, q, v);
    set.check_finite(cd)?;
    crba(model, data, q);
    nonlinear_effects(model, data, q, v);
    let nv = model.nv;
    let b_full = DVector::from_fn(set.nrows, |k, _| {
        -cd.gamma[k] - stab.kd * cd.jv[k] - stab.kp * cd.phi[k]
    });
    ws.partition = partition(&cd.j);
    let p = &ws.partition;
    let jr = cd.j.select_rows(p.rows.iter());
    let br = b_full.select_rows(p.rows.iter());
    let jd = jr.select_columns(p.dependent.iter());
    let ji = jr.select_columns(p.independent.iter());
    let lu = jd.clone().lu();
    let (nd, ni) = (p.dependent.len(), p.independent.len());
    let bmat = if nd > 0 {
        -lu.solve(&ji).ok_or_else(|| singular(set))?
    } else {
        DMatrix::zeros(0, ni)
    };
    let qdd_d0 = if nd > 0 {
        lu.solve(&br).ok_or_else(|| singular(set))?
    } else {
        DVector::zeros(0)
    };
    // The dropped rows must be satisfied too (consistency of redundant constraints).
    let mut n = DMatrix::zeros(nv, ni);
    let mut qdd_p = DVector::zeros(nv);
    for (a, &c) in p.independent.iter().enumerate() {
        n[(c, a)] = 1.0;
    }
    for (k, &c) in p.dependent.iter().enumerate() {
        for a in 0..ni {
            n[(c, a)] = bmat[(k, a)];
        }
        qdd_p[c] = qdd_d0[k];
    }
    let resid = &cd.j * &qdd_p - &b_full;
    if resid.amax() > 1e-7 * b_full.amax().max(1.0) {
        return Err(Error::InconsistentConstraints {
            message: format!("redundant constraint rows disagree by {:.3e}", resid.amax()),
        });
    }
    let m = &data.mass_matrix;
    let rhs_full = DVector::from_fn(nv, |i, _| tau[i] - data.tau[i]) - m * &qdd_p;
    let mr = n.transpose() * m * &n;
    let rr = n.transpose() * rhs_full;
    let z = mr
        .cholesky()
        .ok_or_else(|| Error::SingularMass {
            message: "the reduced mass matrix NᵀMN is not positive definite".into(),
        })?
        .solve(&rr);
    ws.qdd = &n * z + qdd_p;
    ws.n = n;
    Ok(())
}

fn singular(set: &ConstraintSet) -> Error {
    Error::InconsistentConstraints {
        message: format!(
            "the dependent block of J is singular (constraints: {})",
            set.names.join(", ")
        ),
    }
}
