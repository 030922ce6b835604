//! The multiplier form: KKT through a Cholesky factor of M and the Schur complement.
//!
//! With M = W Wᵀ (W = Lᵀ of Featherstone's sparse LTL factor), Y = W⁻¹ Jᵀ (nv × nc) and
//! S = Yᵀ Y = J M⁻¹ Jᵀ (nc × nc):
//!   q̈_free = M⁻¹ (τ − h),  S λ = b − J q̈_free,  q̈ = q̈_free + W⁻ᵀ Y λ,
//! where b = −γ − K_d J v − K_p φ. Redundant or singular constraint sets (S singular) are solved
//! with the minimum-norm λ from S's eigen-decomposition and the rank deficiency is reported; a right
//! side outside range(S) means the constraints have no solution, an error. When M itself is only
//! positive semi-definite (a massless link whose motion the constraints fix, like the seed's rod)
//! the augmented matrix M + ρ JᵀJ replaces M and ρ Jᵀb joins the right side: same q̈ and λ.

use super::Baumgarte;
use crate::algorithm::{Data, bias_forces_after_kinematics, crba_after_kinematics};
use crate::constraints::{ConstraintData, ConstraintSet};
use crate::error::{Error, Result};
use crate::linalg::{
    cholesky_in_place, cholesky_solve, independent_columns, ltl_factor, ltl_solve_l, ltl_solve_lt,
    mat_tr_vec, mat_vec, solve_lower, solve_lower_transpose,
};
use crate::model::MIN_PIVOT_RATIO;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Relative threshold below which a Cholesky pivot of S counts as zero.
const RANK_TOL: f64 = 1e-12;
/// The same threshold on Y = L⁻¹Jᵀ (singular values of Y are square roots of S's eigenvalues).
const RANK_TOL_Y: f64 = 1e-6;

/// Workspace and results of the multiplier form (allocated once per model and constraint set).
#[derive(Clone, Debug)]
pub struct KktWorkspace {
    /// LTL factor of M (or dense Cholesky factor of M + ρ JᵀJ when `augmented`).
    pub l: DMatrix<f64>,
    y: DMatrix<f64>,
    s: DMatrix<f64>,
    /// τ − h (nv).
    pub rhs: DVector<f64>,
    /// Acceleration-level right side b = −γ − K_d J v − K_p φ (nc).
    pub b: DVector<f64>,
    r: DVector<f64>,
    tmp: DVector<f64>,
    /// q̈ (nv).
    pub qdd: DVector<f64>,
    /// λ (nc), in the rows' units (N, N·m, …): force ON the robot.
    pub lambda: DVector<f64>,
    /// Jᵀλ per velocity coordinate (nv).
    pub generalized_force: DVector<f64>,
    /// nc − rank(J M⁻¹ Jᵀ).
    pub rank_deficiency: usize,
    /// M was only semi-definite and the augmented form was used.
    pub augmented: bool,
    /// Accept constraint rows that cannot all be met and return the least-squares λ = S⁺ r
    /// instead of an error (the predictor sets it: integration stages and drift near a singular
    /// configuration make redundant rows disagree slightly). Default false.
    pub allow_inconsistent: bool,
    /// Part of r outside range(S) at the last rank-deficient solve (0 when consistent).
    pub inconsistency: f64,
}

impl KktWorkspace {
    /// Size the workspace for the model (nv) and constraint set (nc).
    pub fn new(model: &Model, set: &ConstraintSet) -> Self {
        let (nv, nc) = (model.nv, set.nrows);
        Self {
            l: DMatrix::zeros(nv, nv),
            y: DMatrix::zeros(nv, nc),
            s: DMatrix::zeros(nc, nc),
            rhs: DVector::zeros(nv),
            b: DVector::zeros(nc),
            r: DVector::zeros(nc),
            tmp: DVector::zeros(nv),
            qdd: DVector::zeros(nv),
            lambda: DVector::zeros(nc),
            generalized_force: DVector::zeros(nv),
            rank_deficiency: 0,
            augmented: false,
            allow_inconsistent: false,
            inconsistency: 0.0,
        }
    }
}

/// Constrained forward dynamics with multipliers at (q, v, τ); results in `ws.qdd`, `ws.lambda`,
/// `ws.generalized_force`; J, φ, γ, J v in `cd`; M in `data.mass_matrix`, h in `data.tau`.
#[allow(clippy::too_many_arguments)]
pub fn constrained_forward_dynamics(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    ws: &mut KktWorkspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    stab: Baumgarte,
) -> Result<()> {
    // A velocity-determined row's force is not along its J row (non-symmetric KKT).
    if let Some(k) = set.items.iter().position(
        |c| matches!(c, crate::constraints::Constraint::Velocity(vc) if vc.velocity_determined),
    ) {
        return Err(Error::Unsupported {
            what: format!(
                "the multiplier form with velocity_determined constraint '{}'",
                set.names[k]
            ),
            why: "its force is not along ∂f/∂v (a non-symmetric KKT system, not implemented); \
                  use formulation: embedded"
                .into(),
        });
    }
    // One kinematics pass at (q, v, q̈ = 0) serves the constraints, M and h.
    set.evaluate(model, data, cd, q, v);
    set.check_finite(cd)?;
    crba_after_kinematics(model, data);
    bias_forces_after_kinematics(model, data);
    for i in 0..model.nv {
        ws.rhs[i] = tau[i] - data.tau[i];
    }
    for k in 0..set.nrows {
        ws.b[k] = -cd.gamma[k] - stab.kd * cd.jv[k] - stab.kp * cd.phi[k];
    }
    factor_mass(model, data, cd, ws)?;
    solve_kkt(model, set, cd, ws)
}

/// Factor M (sparse LTL, `M = LᵀL`), or the augmented M + ρ JᵀJ (dense Cholesky, `L Lᵀ`) when
/// M is only semi-definite.
fn factor_mass(
    model: &Model,
    data: &Data,
    cd: &ConstraintData,
    ws: &mut KktWorkspace,
) -> Result<()> {
    ws.l.copy_from(&data.mass_matrix);
    ws.augmented = false;
    let m = &data.mass_matrix;
    // Each pivot against its own diagonal entry too, not only against max diag(M): a point
    // mass on a 3-axis neck gives a pivot 1e-11 of its entry, far above 1e-14 · max diag, and
    // q̈ made of rounding noise (icub at q = 0 with a fixed base: −2.8e9 rad/s²).
    let pivots_ok = |l: &DMatrix<f64>, diag: &dyn Fn(usize) -> f64| {
        (0..model.nv).find(|&k| l[(k, k)] * l[(k, k)] < MIN_PIVOT_RATIO * diag(k))
    };
    if ltl_factor(&mut ws.l, &model.v_parent, 1e-14).is_ok()
        && pivots_ok(&ws.l, &|k| m[(k, k)]).is_none()
    {
        return Ok(());
    }
    let rho = (0..model.nv)
        .map(|i| m[(i, i)])
        .fold(0.0, f64::max)
        .max(1.0);
    ws.l.copy_from(m);
    let j = &cd.j;
    for a in 0..model.nv {
        for c in 0..model.nv {
            ws.l[(a, c)] += rho * (0..j.nrows()).map(|k| j[(k, a)] * j[(k, c)]).sum::<f64>();
        }
    }
    mat_tr_vec(j, ws.b.as_slice(), ws.tmp.as_mut_slice());
    ws.rhs.axpy(rho, &ws.tmp, 1.0);
    ws.augmented = true;
    let singular = |i: usize| Error::SingularMass {
        message: format!(
            "coordinate '{}' has no inertia (or none independent of the others at this \
             configuration) and no constraint fixes its motion",
            model.v_names[i]
        ),
    };
    cholesky_in_place(&mut ws.l, model.nv, 1e-14).map_err(singular)?;
    let augmented_diag =
        |k: usize| m[(k, k)] + rho * (0..j.nrows()).map(|r| j[(r, k)] * j[(r, k)]).sum::<f64>();
    match pivots_ok(&ws.l, &augmented_diag) {
        Some(k) => Err(singular(k)),
        None => Ok(()),
    }
}

/// `x ← W⁻ᵀ x` and `x ← W⁻¹ x` for the factor W with M = W Wᵀ (W = Lᵀ of the LTL factor,
/// or the dense Cholesky factor when augmented).
fn half_solve(model: &Model, ws_l: &DMatrix<f64>, augmented: bool, x: &mut [f64]) {
    if augmented {
        solve_lower(ws_l, x.len(), x)
    } else {
        ltl_solve_lt(ws_l, &model.v_parent, x)
    }
}
fn half_solve_t(model: &Model, ws_l: &DMatrix<f64>, augmented: bool, x: &mut [f64]) {
    if augmented {
        solve_lower_transpose(ws_l, x.len(), x)
    } else {
        ltl_solve_l(ws_l, &model.v_parent, x)
    }
}

fn solve_kkt(
    model: &Model,
    set: &ConstraintSet,
    cd: &ConstraintData,
    ws: &mut KktWorkspace,
) -> Result<()> {
    let (nv, nc) = (ws.qdd.len(), set.nrows);
    // q̈_free = M⁻¹ (τ − h) = W⁻ᵀ W⁻¹ (τ − h)
    ws.qdd.copy_from(&ws.rhs);
    half_solve(model, &ws.l, ws.augmented, ws.qdd.as_mut_slice());
    half_solve_t(model, &ws.l, ws.augmented, ws.qdd.as_mut_slice());
    ws.lambda.fill(0.0);
    ws.rank_deficiency = 0;
    ws.inconsistency = 0.0;
    if nc == 0 {
        ws.generalized_force.fill(0.0);
        return Ok(());
    }
    // Y = L⁻¹ Jᵀ, S = Yᵀ Y
    for k in 0..nc {
        for i in 0..nv {
            ws.y[(i, k)] = cd.j[(k, i)];
        }
        let mut col = ws.y.column_mut(k);
        half_solve(model, &ws.l, ws.augmented, col.as_mut_slice());
    }
    ws.y.tr_mul_to(&ws.y, &mut ws.s);
    // r = b − J q̈_free
    mat_vec(&cd.j, ws.qdd.as_slice(), ws.r.as_mut_slice());
    for k in 0..nc {
        ws.r[k] = ws.b[k] - ws.r[k];
    }
    ws.lambda.copy_from(&ws.r);
    if cholesky_in_place(&mut ws.s, nc, RANK_TOL).is_ok() {
        cholesky_solve(&ws.s, nc, ws.lambda.as_mut_slice());
    } else {
        min_norm_solve(set, ws)?;
    }
    // q̈ = q̈_free + L⁻ᵀ (Y λ), generalized force Jᵀλ.
    mat_vec(&ws.y, ws.lambda.as_slice(), ws.tmp.as_mut_slice());
    half_solve_t(model, &ws.l, ws.augmented, ws.tmp.as_mut_slice());
    ws.qdd += &ws.tmp;
    mat_tr_vec(
        &cd.j,
        ws.lambda.as_slice(),
        ws.generalized_force.as_mut_slice(),
    );
    Ok(())
}

/// Minimum-norm λ of the singular S λ = r (allocates; off the regular path).
///
/// Column-pivoted QR of Y = W⁻¹Jᵀ picks a maximal independent set I of rows (‖r_kk‖ above
/// `RANK_TOL_Y` relative). r is projected onto range(S) = span S[:, I] (the part outside it is
/// the rows' inconsistency: an error above 1e-7 relative, rounding below); S_II λ_I = r̂_I gives
/// one solution λ₀ (λ_D = 0), and the minimum-norm one is λ₀ minus its projection on
/// null(S) = span{e_d − S_II⁻¹ S_Id}: together λ = S⁺ r, smooth in the state.
fn min_norm_solve(set: &ConstraintSet, ws: &mut KktWorkspace) -> Result<()> {
    let nc = set.nrows;
    ws.y.tr_mul_to(&ws.y, &mut ws.s);
    let ind = independent_columns(&ws.y, RANK_TOL_Y);
    let dep: Vec<usize> = (0..nc).filter(|k| !ind.contains(k)).collect();
    // Project r onto range(S) = span S[:, I] (unique, whichever independent set was picked, so
    // λ varies smoothly with the state); what is left over is the inconsistency of the rows.
    let s_cols = ws.s.select_columns(ind.iter());
    let gram = (s_cols.transpose() * &s_cols).cholesky().ok_or_else(|| {
        Error::InconsistentConstraints {
            message: "the independent constraint rows are numerically singular".into(),
        }
    })?;
    let r_hat = &s_cols * gram.solve(&(s_cols.transpose() * &ws.r));
    let inconsistency = (&ws.r - &r_hat).amax();
    ws.inconsistency = inconsistency;
    let scale = ws.r.amax().max(1.0);
    if inconsistency > 1e-7 * scale && !ws.allow_inconsistent {
        let worst = (&ws.r - &r_hat).iamax();
        let name = set
            .ranges
            .iter()
            .position(|rg| rg.contains(&worst))
            .map(|k| set.names[k].clone());
        return Err(Error::InconsistentConstraints {
            message: format!(
                "the constraint accelerations cannot all be met (rank {} of {nc}; largest \
                 violation {inconsistency:.3e} on a row of '{}')",
                ind.len(),
                name.unwrap_or_default()
            ),
        });
    }
    let s_ii = ws.s.select_rows(ind.iter()).select_columns(ind.iter());
    let chol = s_ii
        .cholesky()
        .ok_or_else(|| Error::InconsistentConstraints {
            message: "the independent constraint rows are numerically singular".into(),
        })?;
    let lam_i = chol.solve(&r_hat.select_rows(ind.iter()));
    let mut lambda = DVector::zeros(nc);
    for (a, &k) in ind.iter().enumerate() {
        lambda[k] = lam_i[a];
    }
    if !dep.is_empty() {
        let s_id = ws.s.select_rows(ind.iter()).select_columns(dep.iter());
        let w = chol.solve(&s_id);
        let mut n = DMatrix::zeros(nc, dep.len());
        for (b, &d) in dep.iter().enumerate() {
            n[(d, b)] = 1.0;
            for (a, &k) in ind.iter().enumerate() {
                n[(k, b)] = -w[(a, b)];
            }
        }
        let ntn = n.transpose() * &n;
        let coef = ntn.cholesky().map(|c| c.solve(&(n.transpose() * &lambda)));
        if let Some(coef) = coef {
            lambda -= &n * coef;
        }
    }
    ws.lambda.copy_from(&lambda);
    ws.rank_deficiency = dep.len();
    Ok(())
}
