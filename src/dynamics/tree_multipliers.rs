//! The multiplier form on a large tree in O(n·m² + m³) time and O(n·m) memory for m
//! constraint rows, without M: q̈_free = M⁻¹(τ − h) by ABA; on ABA's factorization
//! M⁻¹ = Ψᵀ D⁻¹ Ψ, each row of J's innovations E = Ψ Jᵀ by ABA's force pass
//! ([`crate::algorithm::aba_innovations`]) and the Schur complement S = J M⁻¹ Jᵀ = Eᵀ D⁻¹ E
//! as a Gram matrix (positive semi-definite to rounding, as the dense path's Yᵀ Y, so redundant
//! rows are found as reliably); then the same minimum-norm λ = S⁺ r as the dense path
//! ([`super::multipliers`]) and q̈ = q̈_free + Ψᵀ D⁻¹ (E λ), one acceleration pass. For a fixed
//! number of rows — a chain closed into a loop, a rope held at both ends — the cost is linear
//! in n where the dense path's is cubic on a chain.
//!
//! Taken where [`super::takes_linear_path`] says so. Where ABA's pivots fail the dense path's
//! checks (a link with no inertia of its own that the constraints fix), the caller takes the
//! dense path and its augmented form. M and h are not formed; λ, q̈, the generalized force,
//! the rank deficiency and the inconsistency are those the dense path reports.

use super::multipliers::{KktOptions, KktWorkspace, min_norm_solve, velocity_determined};
use super::tree::{TreeWorkspace, tree_forward_dynamics};
use crate::algorithm::{Data, aba_from_innovations, aba_innovations, innovations_product};
use crate::constraints::{ConstraintData, ConstraintSet};
use crate::error::Result;
use crate::linalg::mat_tr_vec;
use crate::model::Model;
use nalgebra::Vector6;

/// Workspace of the linear-time multiplier form: two spatial vectors per body, one row of J
/// and a zero vector (nv each).
#[derive(Clone, Debug, Default)]
pub struct TreeKktWorkspace {
    tree: TreeWorkspace,
    forces: Vec<Vector6<f64>>,
    accelerations: Vec<Vector6<f64>>,
    row: Vec<f64>,
    zeros: Vec<f64>,
}

impl TreeKktWorkspace {
    /// Sized for the model.
    pub fn new(model: &Model) -> Self {
        Self {
            tree: TreeWorkspace::new(model),
            forces: vec![Vector6::zeros(); model.nbodies()],
            accelerations: vec![Vector6::zeros(); model.nbodies()],
            row: vec![0.0; model.nv],
            zeros: vec![0.0; model.nv],
        }
    }

    /// The unconstrained path's workspace (M's diagonal and ABA's pivots).
    pub fn tree(&mut self) -> &mut TreeWorkspace {
        &mut self.tree
    }

    /// ABA's factors of M at q into `data` (at zero velocity and torque), for the mass metric
    /// of a projection ([`Self::innovations`], [`Self::from_innovations`]). False where a pivot
    /// fails the dense path's checks: the dense metric decides there.
    pub fn factor_metric(&mut self, model: &Model, data: &mut Data, q: &[f64]) -> bool {
        if self.zeros.len() != model.nv || self.forces.len() != model.nbodies() {
            *self = Self::new(model);
        }
        let zeros = &self.zeros;
        tree_forward_dynamics(model, data, &mut self.tree, q, zeros, zeros)
    }

    /// u = Ψ b on the factors in `data` ([`crate::algorithm::aba_innovations`]).
    pub fn innovations(&mut self, model: &Model, data: &Data, b: &[f64], u: &mut [f64]) {
        aba_innovations(model, data, b, u, &mut self.forces);
    }

    /// x = Ψᵀ D⁻¹ u on the factors in `data`: M⁻¹ b for u = Ψ b.
    pub fn from_innovations(&mut self, model: &Model, data: &Data, u: &[f64], x: &mut [f64]) {
        aba_from_innovations(model, data, u, x, &mut self.accelerations);
    }
}

/// The multiplier form at (q, v, τ) by ABA: results in `kkt.qdd`, `kkt.lambda`,
/// `kkt.generalized_force` (and its rank deficiency and inconsistency), the rows in `cd`.
/// `Ok(false)` when the dense path must decide: a constraint whose force is not along its row
/// (that path names it), or ABA's pivots failing that path's checks.
#[allow(clippy::too_many_arguments)]
pub fn tree_constrained_forward_dynamics(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    kkt: &mut KktWorkspace,
    ws: &mut TreeKktWorkspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    opts: KktOptions,
) -> Result<bool> {
    let (nv, nc) = (model.nv, set.nrows);
    if velocity_determined(set).is_some() {
        return Ok(false);
    }
    if ws.row.len() != nv || ws.forces.len() != model.nbodies() {
        *ws = TreeKktWorkspace::new(model);
    }
    if !opts.rows_evaluated {
        set.evaluate(model, data, cd, opts.t, q, v);
    }
    set.check_finite(cd)?;
    // ABA recomputes the same placements and velocities the rows were evaluated at.
    if !tree_forward_dynamics(model, data, &mut ws.tree, q, v, tau) {
        return Ok(false);
    }
    let stab = opts.gains;
    for k in 0..nc {
        kkt.b[k] = -cd.gamma[k] - stab.kd * cd.jv[k] - stab.kp * cd.phi[k];
    }
    // E's column k = Ψ (row k of J)ᵀ; J is stored by columns, so its row k is strided.
    let j = cd.j.as_slice();
    for k in 0..nc {
        for (c, x) in ws.row.iter_mut().enumerate() {
            *x = j[c * nc + k];
        }
        let col = &mut kkt.y.as_mut_slice()[k * nv..(k + 1) * nv];
        aba_innovations(model, data, &ws.row, col, &mut ws.forces);
    }
    // S's lower triangle, Eᵀ D⁻¹ E.
    let e = kkt.y.as_slice();
    for a in 0..nc {
        for b in a..nc {
            let (ea, eb) = (&e[a * nv..(a + 1) * nv], &e[b * nv..(b + 1) * nv]);
            kkt.s[(b, a)] = innovations_product(model, data, ea, eb);
        }
    }
    // r = b − J q̈_free.
    let qdd_free = data.qdd.as_slice();
    for k in 0..nc {
        let jq: f64 = (0..nv).map(|c| j[c * nc + k] * qdd_free[c]).sum();
        kkt.r[k] = kkt.b[k] - jq;
    }
    kkt.lambda.as_mut_slice().fill(0.0);
    kkt.rank_deficiency = 0;
    kkt.inconsistency = 0.0;
    kkt.augmented = false;
    min_norm_solve(set, kkt, opts.allow_inconsistent)?;
    // q̈ = q̈_free + Ψᵀ D⁻¹ (E λ); the generalized force Jᵀλ.
    ws.row.fill(0.0);
    for k in 0..nc {
        let lk = kkt.lambda[k];
        for (x, ek) in ws
            .row
            .iter_mut()
            .zip(&kkt.y.as_slice()[k * nv..(k + 1) * nv])
        {
            *x += lk * ek;
        }
    }
    aba_from_innovations(
        model,
        data,
        &ws.row,
        kkt.tmp.as_mut_slice(),
        &mut ws.accelerations,
    );
    for i in 0..nv {
        kkt.qdd[i] = data.qdd[i] + kkt.tmp[i];
    }
    mat_tr_vec(
        &cd.j,
        kkt.lambda.as_slice(),
        kkt.generalized_force.as_mut_slice(),
    );
    Ok(true)
}
