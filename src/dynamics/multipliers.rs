//! The multiplier form: KKT through a Cholesky factor of M and the Schur complement.
//!
//! With M = L Lᵀ, Y = L⁻¹ Jᵀ (nv × nc) and S = Yᵀ Y = J M⁻¹ Jᵀ (nc × nc):
//!   q̈_free = M⁻¹ (τ − h),  S λ = b − J q̈_free,  q̈ = q̈_free + L⁻ᵀ Y λ,
//! where b = −γ − K_d J v − K_p φ. Redundant or singular constraint sets (S singular) are solved
//! with the minimum-norm λ from S's eigen-decomposition and the rank deficiency is reported; a right
//! side outside range(S) means the constraints have no solution, an error. When M itself is only
//! positive semi-definite (a massless link whose motion the constraints fix, like the seed's rod)
//! the augmented matrix M + ρ JᵀJ replaces M and ρ Jᵀb joins the right side: same q̈ and λ.

use super::Baumgarte;
use super::dense::{
    cholesky_in_place, cholesky_solve, mat_tr_vec, mat_vec, solve_lower, solve_lower_transpose,
};
use crate::algorithm::{Data, crba, nonlinear_effects};
use crate::constraints::{ConstraintData, ConstraintSet};
use crate::error::{Error, Result};
use crate::model::Model;
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// Relative threshold below which a pivot or eigenvalue of S counts as zero.
const RANK_TOL: f64 = 1e-10;

/// Workspace and results of the multiplier form (allocated once per model and constraint set).
#[derive(Clone, Debug)]
pub struct KktWorkspace {
    /// Cholesky factor L of M (or of M + ρ JᵀJ when `augmented`).
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
}

impl KktWorkspace {
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
    set.evaluate(model, data, cd, q, v);
    crba(model, data, q);
    nonlinear_effects(model, data, q, v);
    for i in 0..model.nv {
        ws.rhs[i] = tau[i] - data.tau[i];
    }
    for k in 0..set.nrows {
        ws.b[k] = -cd.gamma[k] - stab.kd * cd.jv[k] - stab.kp * cd.phi[k];
    }
    factor_mass(model, data, cd, ws)?;
    solve_kkt(set, cd, ws)
}

/// L from M, or from M + ρ JᵀJ when M is semi-definite.
fn factor_mass(
    model: &Model,
    data: &Data,
    cd: &ConstraintData,
    ws: &mut KktWorkspace,
) -> Result<()> {
    ws.l.copy_from(&data.mass_matrix);
    ws.augmented = false;
    if cholesky_in_place(&mut ws.l, 1e-14).is_ok() {
        return Ok(());
    }
    let m = &data.mass_matrix;
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
    cholesky_in_place(&mut ws.l, 1e-14).map_err(|i| Error::SingularMass {
        message: format!(
            "coordinate '{}' has no inertia and no constraint fixes its motion",
            model.v_names[i]
        ),
    })
}

fn solve_kkt(set: &ConstraintSet, cd: &ConstraintData, ws: &mut KktWorkspace) -> Result<()> {
    let (nv, nc) = (ws.qdd.len(), set.nrows);
    // q̈_free = M⁻¹ (τ − h)
    ws.qdd.copy_from(&ws.rhs);
    cholesky_solve(&ws.l, ws.qdd.as_mut_slice());
    ws.lambda.fill(0.0);
    ws.rank_deficiency = 0;
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
        solve_lower(&ws.l, col.as_mut_slice());
    }
    ws.y.tr_mul_to(&ws.y, &mut ws.s);
    // r = b − J q̈_free
    mat_vec(&cd.j, ws.qdd.as_slice(), ws.r.as_mut_slice());
    for k in 0..nc {
        ws.r[k] = ws.b[k] - ws.r[k];
    }
    ws.lambda.copy_from(&ws.r);
    if cholesky_in_place(&mut ws.s, RANK_TOL).is_ok() {
        cholesky_solve(&ws.s, ws.lambda.as_mut_slice());
    } else {
        min_norm_solve(set, ws)?;
    }
    // q̈ = q̈_free + L⁻ᵀ (Y λ), generalized force Jᵀλ.
    mat_vec(&ws.y, ws.lambda.as_slice(), ws.tmp.as_mut_slice());
    solve_lower_transpose(&ws.l, ws.tmp.as_mut_slice());
    ws.qdd += &ws.tmp;
    mat_tr_vec(
        &cd.j,
        ws.lambda.as_slice(),
        ws.generalized_force.as_mut_slice(),
    );
    Ok(())
}

/// Minimum-norm λ of the singular S λ = r (eigen-decomposition; allocates, off the regular path).
fn min_norm_solve(set: &ConstraintSet, ws: &mut KktWorkspace) -> Result<()> {
    ws.y.tr_mul_to(&ws.y, &mut ws.s);
    let eig = SymmetricEigen::new(ws.s.clone());
    let smax = eig.eigenvalues.amax().max(f64::MIN_POSITIVE);
    let mut lambda = DVector::zeros(set.nrows);
    let mut rank = 0;
    for (k, &e) in eig.eigenvalues.iter().enumerate() {
        if e > RANK_TOL * smax {
            let u = eig.eigenvectors.column(k);
            lambda += u * (u.dot(&ws.r) / e);
            rank += 1;
        }
    }
    let resid = &ws.s * &lambda - &ws.r;
    let scale = ws.r.amax().max(1.0);
    if resid.amax() > 1e-7 * scale {
        let worst = resid.iamax();
        let name = set
            .ranges
            .iter()
            .position(|rg| rg.contains(&worst))
            .map(|k| set.names[k].clone())
            .unwrap_or_default();
        return Err(Error::InconsistentConstraints {
            message: format!(
                "the constraint accelerations cannot all be met (rank {rank} of {}; largest \
                 violation {:.3e} on a row of '{name}')",
                set.nrows,
                resid.amax()
            ),
        });
    }
    ws.lambda.copy_from(&lambda);
    ws.rank_deficiency = set.nrows - rank;
    Ok(())
}
