//! The differentiated KKT system, solved for the three inputs (q, v, τ) through M⁻¹ (or the
//! augmented M + ρJᵀJ) and the Schur complement K = J M⁻¹ Jᵀ.

use super::DerivativeData;
use super::aba::{invert_factor, invert_mass};
use crate::algorithm::Data;
use crate::constraints::ConstraintData;
use crate::error::{Error, Result};
use crate::linalg::{
    gemm_into, gemm_nt_into, gemm_tr_into, inverse_from_cholesky, semidefinite_cholesky,
    semidefinite_solve, semidefinite_solve_columns,
};
use crate::model::Model;

/// Rank test of J M⁻¹ Jᵀ: a row whose Cholesky pivot is below this fraction of the largest
/// diagonal is dependent. Looser than the multiplier solve's first attempt (1e-12): an exactly
/// dependent row's pivot is rounding times the condition number, and 1e-12 missed the
/// dependent wheel row of a floating mobile manipulator state (tests/it/derivatives_fd.rs); 1e-9
/// still keeps rows at a singular-value ratio above ~3e-5.
const RANK_TOL: f64 = 1e-9;

/// M⁻¹ into `dd.minv`, or — when only the constraints give some coordinate inertia, as in
/// the multiplier solve — the inverse of M + ρ JᵀJ (ρ = max(1, max diag M)), which the KKT
/// system admits as well: `(M + ρJᵀJ) q̈ − Jᵀλ = R₁ + ρ Jᵀ R₂` with `J q̈ = R₂`.
pub(crate) fn invert_mass_or_augmented(
    model: &Model,
    data: &Data,
    cd: &ConstraintData,
    dd: &mut DerivativeData,
) -> Result<()> {
    let nv = model.nv;
    let m = &data.mass_matrix;
    dd.rho = 0.0;
    if invert_mass(model, m, dd).is_ok() {
        return Ok(());
    }
    dd.rho = (0..nv).map(|i| m[(i, i)]).fold(1.0, f64::max);
    dd.chol.view_mut((0, 0), (nv, nv)).copy_from(m);
    let j = &cd.j;
    for a in 0..nv {
        for b in 0..nv {
            dd.chol[(a, b)] += dd.rho * (0..j.nrows()).map(|k| j[(k, a)] * j[(k, b)]).sum::<f64>();
        }
    }
    invert_factor(nv, dd).map_err(|i| Error::SingularMass {
        message: format!(
            "coordinate '{}' has no inertia and no constraint fixes its motion",
            model.v_names[i]
        ),
    })
}

/// Solves the differentiated KKT system for the three inputs through M⁻¹ and
/// K = J M⁻¹ Jᵀ: K ∂λ = R₂ − J M⁻¹ R₁, ∂q̈ = M⁻¹ (R₁ + Jᵀ ∂λ) (M⁻¹ of the augmented M and
/// R₁ + ρ Jᵀ R₂ when ρ > 0).
pub(crate) fn solve_kkt_derivatives(cd: &ConstraintData, dd: &mut DerivativeData) {
    let j = &cd.j;
    gemm_nt_into(&mut dd.minv_jt, 1.0, &dd.minv, j, 0.0);
    gemm_into(&mut dd.schur, 1.0, j, &dd.minv_jt, 0.0);
    let rank = semidefinite_cholesky(&mut dd.schur, RANK_TOL, &mut dd.dropped);
    dd.lambda_unique = rank == j.nrows();
    if dd.lambda_unique {
        // Full rank: K⁻¹ once, then a product per input instead of triangular solves per
        // column (the factor in `schur` becomes L⁻¹; nothing else reads it then).
        inverse_from_cholesky(&mut dd.schur, j.nrows(), &mut dd.schur_inv);
    }
    null_space_of_schur(j, dd);

    solve_state_input(j, dd, Input::Q);
    solve_state_input(j, dd, Input::V);
    // τ: R₁ = 1, R₂ = 0.
    if !dd.with_tau {
        return;
    }
    dd.rhs_v.copy_from(&dd.minv);
    // −J M⁻¹ = −(M⁻¹Jᵀ)ᵀ, M⁻¹ being symmetric.
    for (r, row) in dd.minv_jt.column_iter().enumerate() {
        for (c, x) in row.iter().enumerate() {
            dd.rhs_c[(r, c)] = -x;
        }
    }
    solve_columns(dd, Input::Tau);
}

/// Input q or v: R₁ = −∂(RNEA − Jᵀλ)/∂x, R₂ = −rows_dx; rhs_v = M⁻¹ R₁ (augmented: R₁ + ρ JᵀR₂),
/// rhs_c = R₂ − J rhs_v, then the solve.
fn solve_state_input(j: &nalgebra::DMatrix<f64>, dd: &mut DerivativeData, input: Input) {
    let DerivativeData {
        dtau_dq,
        dtau_dv,
        rows_dq,
        rows_dv,
        r1,
        rhs_v,
        rhs_c,
        minv,
        rho,
        ..
    } = dd;
    let (dtau, rows) = match input {
        Input::Q => (&*dtau_dq, &*rows_dq),
        _ => (&*dtau_dv, &*rows_dv),
    };
    if *rho == 0.0 {
        gemm_into(rhs_v, -1.0, minv, dtau, 0.0);
    } else {
        r1.copy_from(dtau);
        r1.neg_mut();
        gemm_tr_into(r1, -*rho, j, rows, 1.0);
        gemm_into(rhs_v, 1.0, minv, r1, 0.0);
    }
    gemm_into(rhs_c, -1.0, j, rhs_v, 0.0);
    *rhs_c -= rows;
    solve_columns(dd, input);
}

#[derive(Clone, Copy)]
enum Input {
    Q,
    V,
    Tau,
}

/// With dependent rows, an orthonormal basis of null(K), K = J M⁻¹ Jᵀ, into `dd.null_basis`:
/// for each dropped row d, c_d = (−K_II⁻¹ K_Id, 1), then Gram–Schmidt.
fn null_space_of_schur(j: &nalgebra::DMatrix<f64>, dd: &mut DerivativeData) {
    let nc = j.nrows();
    dd.n_null = 0;
    for d in 0..nc {
        if !dd.dropped[d] {
            continue;
        }
        let k = dd.n_null;
        for r in 0..nc {
            // −K[r, d] = −Σ_i J[r, i] (M⁻¹Jᵀ)[i, d]
            dd.null_basis[(r, k)] = -(0..j.ncols())
                .map(|i| j[(r, i)] * dd.minv_jt[(i, d)])
                .sum::<f64>();
        }
        semidefinite_solve(
            &dd.schur,
            &dd.dropped,
            dd.null_basis.column_mut(k).as_mut_slice(),
        );
        dd.null_basis[(d, k)] = 1.0;
        for p in 0..k {
            let dot = dd.null_basis.column(p).dot(&dd.null_basis.column(k));
            for r in 0..nc {
                dd.null_basis[(r, k)] -= dot * dd.null_basis[(r, p)];
            }
        }
        let n = dd.null_basis.column(k).norm();
        dd.null_basis.column_mut(k).unscale_mut(n);
        dd.n_null += 1;
    }
}

/// ∂λ = K⁺(rhs_c), ∂q̈ = rhs_v + M⁻¹Jᵀ ∂λ into the matrices of `input`. With dependent rows
/// the right-hand side is first projected onto range(K), so q̈'s derivative is that of the
/// multiplier solve's least-squares reconciliation of the rows (λ = K⁺ r), not of a choice of
/// rows to drop: the two differ where the rows disagree, as inside a Runge–Kutta step.
fn solve_columns(dd: &mut DerivativeData, input: Input) {
    let DerivativeData {
        schur,
        schur_inv,
        dropped,
        rhs_c,
        rhs_c_scratch,
        rhs_v,
        minv_jt,
        null_basis,
        n_null,
        lambda_unique,
        ..
    } = dd;
    if *lambda_unique {
        gemm_into(rhs_c_scratch, 1.0, schur_inv, rhs_c, 0.0);
        rhs_c.copy_from(rhs_c_scratch);
    }
    for c in 0..rhs_c.ncols() {
        for k in 0..*n_null {
            let dot = null_basis.column(k).dot(&rhs_c.column(c));
            for r in 0..rhs_c.nrows() {
                rhs_c[(r, c)] -= dot * null_basis[(r, k)];
            }
        }
    }
    if !*lambda_unique {
        semidefinite_solve_columns(schur, dropped, rhs_c);
    }
    gemm_into(rhs_v, 1.0, minv_jt, rhs_c, 1.0);
    let (dqdd, dlambda) = match input {
        Input::Q => (&mut dd.dqdd_dq, &mut dd.dlambda_dq),
        Input::V => (&mut dd.dqdd_dv, &mut dd.dlambda_dv),
        Input::Tau => (&mut dd.dqdd_dtau, &mut dd.dlambda_dtau),
    };
    dqdd.copy_from(&dd.rhs_v);
    if dd.lambda_unique {
        dlambda.copy_from(&dd.rhs_c);
    } else {
        // λ is not unique (dependent rows): it has no derivative; zero, as documented.
        dlambda.as_mut_slice().fill(0.0);
    }
}
