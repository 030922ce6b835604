//! The multiplier form: KKT through a Cholesky factor of M and the Schur complement.
//!
//! With M = W Wᵀ (W = Lᵀ of Featherstone's sparse LTL factor), Y = W⁻¹ Jᵀ (nv × nc) and
//! S = Yᵀ Y = J M⁻¹ Jᵀ (nc × nc):
//!   q̈_free = M⁻¹ (τ − h),  S λ = b − J q̈_free,  q̈ = q̈_free + W⁻ᵀ Y λ,
//! where b = −γ − K_d J v − K_p φ. λ = S⁺ r, the minimum-norm solution (`linalg::MinNormSolver`:
//! S⁻¹ r when S is regular), so redundant or singular constraint sets are solved too and their
//! rank deficiency is reported; a right
//! side outside range(S) means the constraints have no solution, an error. When M itself is only
//! positive semi-definite (a massless link whose motion the constraints fix, like the seed's rod)
//! the augmented matrix M + ρ JᵀJ replaces M and ρ Jᵀb joins the right side: same q̈ and λ.

use super::{Baumgarte, disagree_beyond_rounding};
use crate::algorithm::{DENSE_EAGER_NV, Data, bias_forces_after_kinematics, crba_after_kinematics};
use crate::constraints::{ConstraintData, ConstraintSet};
use crate::error::{Error, Result};
use crate::linalg::{
    MinNormSolver, cholesky_in_place, dot_unrolled, ltl_factor, ltl_solve_l, ltl_solve_lt,
    ltl_solve_lt_rows, mat_tr_vec, mat_vec, solve_lower, solve_lower_transpose,
};
use crate::model::MIN_PIVOT_RATIO;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// The threshold on the pivots of S = YᵀY relative to max diag(S): a row
/// whose part outside the span of the others is below 1e-6 of the longest column of Y is
/// dependent (singular values of Y are square roots of S's eigenvalues).
const RANK_TOL_PIVOT: f64 = 1e-12;

/// Workspace and results of the multiplier form (allocated once per model and constraint set).
#[derive(Clone, Debug)]
pub struct KktWorkspace {
    /// LTL factor of M (or dense Cholesky factor of M + ρ JᵀJ when `augmented`).
    pub l: DMatrix<f64>,
    /// Reciprocals of the LTL factor's diagonal (nv).
    pub l_inv_diag: DVector<f64>,
    pub(super) y: DMatrix<f64>,
    /// Yᵀ by rows while it is solved for (nv × nc, row i at `i·nc`).
    y_rows: Vec<f64>,
    /// First and one-past-last non-zero row of each column of Y.
    support: Vec<(usize, usize)>,
    /// S's lower triangle.
    pub(super) s: DMatrix<f64>,
    /// τ − h (nv).
    pub rhs: DVector<f64>,
    /// Acceleration-level right side b = −γ − K_d J v − K_p φ (nc).
    pub b: DVector<f64>,
    pub(super) r: DVector<f64>,
    pub(super) tmp: DVector<f64>,
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
    /// Part of r outside range(S) at the last solve (0 when consistent).
    pub inconsistency: f64,
    /// The factor of S and its solves.
    pub(super) min_norm: MinNormSolver,
}

impl KktWorkspace {
    /// Size the workspace for the model (nv) and constraint set (nc).
    pub fn new(model: &Model, set: &ConstraintSet) -> Self {
        let (nv, nc) = (model.nv, set.nrows);
        Self {
            // A large model's is sized by its first dense factor (`factor_mass`).
            l: if nv <= DENSE_EAGER_NV {
                DMatrix::zeros(nv, nv)
            } else {
                DMatrix::zeros(0, 0)
            },
            l_inv_diag: DVector::zeros(nv),
            y: DMatrix::zeros(nv, nc),
            y_rows: vec![0.0; nv * nc],
            support: vec![(0, 0); nc],
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
            inconsistency: 0.0,
            min_norm: MinNormSolver::new(nc),
        }
    }
}

/// How one multiplier-form evaluation is done: the settings of that call alone, never kept in
/// the workspace between calls. A `Baumgarte` converts to the defaults with those gains.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KktOptions {
    /// Time [s] of the evaluation (what `velocity` rows f(q, v, t) read).
    pub t: f64,
    /// Baumgarte stabilisation gains of this evaluation.
    pub gains: Baumgarte,
    /// Accept constraint rows that cannot all be met and return the least-squares λ = S⁺ r
    /// instead of an error (integration stages and drift near a singular configuration make
    /// redundant rows disagree slightly).
    pub allow_inconsistent: bool,
    /// The kinematics in `data` and the rows in `cd` are already those of this call's (q, v)
    /// (`ConstraintSet::evaluate` ran there and nothing has written them since), so that pass
    /// is skipped.
    pub rows_evaluated: bool,
}

impl From<Baumgarte> for KktOptions {
    fn from(gains: Baumgarte) -> Self {
        KktOptions {
            gains,
            ..Default::default()
        }
    }
}

/// Constrained forward dynamics with multipliers at (q, v, τ); results in `ws.qdd`, `ws.lambda`,
/// `ws.generalized_force`; J, φ, γ, J v in `cd`; M's lower triangle in `data.mass_matrix` (what the
/// factors read; [`crate::algorithm::crba`]), h in `data.tau`.
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
    opts: impl Into<KktOptions>,
) -> Result<()> {
    let opts = opts.into();
    let stab = opts.gains;
    if let Some(k) = velocity_determined(set) {
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
    if !opts.rows_evaluated {
        set.evaluate(model, data, cd, opts.t, q, v);
    }
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
    solve_kkt(model, set, cd, ws, opts.allow_inconsistent)
}

/// The first velocity-determined constraint of `set`: its force is not along its J row (a
/// non-symmetric KKT system), so the multiplier form does not take it.
pub(super) fn velocity_determined(set: &ConstraintSet) -> Option<usize> {
    set.items.iter().position(
        |c| matches!(c, crate::constraints::Constraint::Velocity(vc) if vc.velocity_determined),
    )
}

/// Factor M (sparse LTL, `M = LᵀL`), or the augmented M + ρ JᵀJ (dense Cholesky, `L Lᵀ`) when
/// M is only semi-definite.
fn factor_mass(
    model: &Model,
    data: &Data,
    cd: &ConstraintData,
    ws: &mut KktWorkspace,
) -> Result<()> {
    if ws.l.shape() != data.mass_matrix.shape() {
        ws.l = DMatrix::zeros(model.nv, model.nv);
    }
    ws.l.copy_from(&data.mass_matrix);
    ws.augmented = false;
    let m = &data.mass_matrix;
    // Each pivot against its own diagonal entry too, not only against max diag(M): a point
    // mass on a 3-axis neck gives a pivot 1e-11 of its entry, far above 1e-14 · max diag, and
    // q̈ made of rounding noise (icub at q = 0 with a fixed base: −2.8e9 rad/s²).
    // (`<` and `<=` differ only at exact equality: that mutation is equivalent.)
    let pivots_ok = |l: &DMatrix<f64>, diag: &dyn Fn(usize) -> f64| {
        (0..model.nv).find(|&k| l[(k, k)] * l[(k, k)] < MIN_PIVOT_RATIO * diag(k))
    };
    if ltl_factor(
        &mut ws.l,
        &model.v_parent,
        &model.v_subtree_end,
        1e-14,
        ws.l_inv_diag.as_mut_slice(),
    )
    .is_ok()
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
    // No bundled or reference system fails this check (a scene whose massless coordinates the
    // constraints do not fix is refused when it loads, model/check.rs); it guards states
    // where the constraints' rank drops at a singular configuration, which no test reaches,
    // so a mutation that lowers this bound survives the tests.
    let augmented_diag =
        |k: usize| m[(k, k)] + rho * (0..j.nrows()).map(|r| j[(r, k)] * j[(r, k)]).sum::<f64>();
    match pivots_ok(&ws.l, &augmented_diag) {
        Some(k) => Err(singular(k)),
        None => Ok(()),
    }
}

/// `x ← W⁻ᵀ x` and `x ← W⁻¹ x` for the factor W with M = W Wᵀ (W = Lᵀ of the LTL factor,
/// or the dense Cholesky factor when augmented).
fn half_solve(
    model: &Model,
    ws_l: &DMatrix<f64>,
    inv: &DVector<f64>,
    augmented: bool,
    x: &mut [f64],
) {
    if augmented {
        solve_lower(ws_l, x.len(), x)
    } else {
        ltl_solve_lt(ws_l, inv.as_slice(), &model.v_parent, x)
    }
}
fn half_solve_t(
    model: &Model,
    ws_l: &DMatrix<f64>,
    inv: &DVector<f64>,
    augmented: bool,
    x: &mut [f64],
) {
    if augmented {
        solve_lower_transpose(ws_l, x.len(), x)
    } else {
        ltl_solve_l(ws_l, inv.as_slice(), &model.v_parent, x)
    }
}

fn solve_kkt(
    model: &Model,
    set: &ConstraintSet,
    cd: &ConstraintData,
    ws: &mut KktWorkspace,
    allow_inconsistent: bool,
) -> Result<()> {
    let nc = set.nrows;
    // With M = W Wᵀ and Y = W⁻¹ Jᵀ: q̈ = M⁻¹ (τ − h + Jᵀλ) = W⁻ᵀ (u + Y λ), u = W⁻¹ (τ − h),
    // and J q̈_free = J W⁻ᵀ u = Yᵀ u. One solve with Wᵀ at the end instead of one for q̈_free
    // and one for M⁻¹ Jᵀ λ (the sparse solves walk the tree: 5.4 k instructions each on
    // talos_reduced). ws.qdd holds u until then.
    ws.qdd.copy_from(&ws.rhs);
    half_solve(
        model,
        &ws.l,
        &ws.l_inv_diag,
        ws.augmented,
        ws.qdd.as_mut_slice(),
    );
    ws.lambda.as_mut_slice().fill(0.0);
    ws.rank_deficiency = 0;
    ws.inconsistency = 0.0;
    if nc == 0 {
        ws.generalized_force.as_mut_slice().fill(0.0);
    } else {
        add_constraint_forces(model, set, cd, ws, allow_inconsistent)?;
    }
    half_solve_t(
        model,
        &ws.l,
        &ws.l_inv_diag,
        ws.augmented,
        ws.qdd.as_mut_slice(),
    );
    Ok(())
}

/// λ from S λ = r, `ws.qdd` (u) += Y λ and the generalized force Jᵀλ, for nc > 0 rows.
fn add_constraint_forces(
    model: &Model,
    set: &ConstraintSet,
    cd: &ConstraintData,
    ws: &mut KktWorkspace,
    allow_inconsistent: bool,
) -> Result<()> {
    let (nv, nc) = (ws.qdd.len(), set.nrows);
    // Y = W⁻¹ Jᵀ (L⁻ᵀ Jᵀ for the LTL factor) with each column's non-zero rows: a row of J on
    // one branch (a foot) keeps its column of Y on that branch and its ancestors.
    if ws.augmented {
        for k in 0..nc {
            for i in 0..nv {
                ws.y[(i, k)] = cd.j[(k, i)];
            }
            solve_lower(&ws.l, nv, ws.y.column_mut(k).as_mut_slice());
        }
    } else {
        // All nc columns in one walk of the tree: Jᵀ by rows is J's column-major storage.
        ws.y_rows.copy_from_slice(cd.j.as_slice());
        ltl_solve_lt_rows(
            &ws.l,
            ws.l_inv_diag.as_slice(),
            &model.v_parent,
            &mut ws.y_rows,
            nc,
        );
        for (i, row) in ws.y_rows.chunks_exact(nc).enumerate() {
            for (k, &x) in row.iter().enumerate() {
                ws.y[(i, k)] = x;
            }
        }
    }
    for k in 0..nc {
        let col = ws.y.column(k);
        let first = col.iter().position(|&x| x != 0.0).unwrap_or(0);
        let last = col.iter().rposition(|&x| x != 0.0).map_or(0, |i| i + 1);
        ws.support[k] = (first, last.max(first));
    }
    schur_lower(ws, nv, nc);
    // r = b − J q̈_free = b − Yᵀ u, each over its column's non-zero range.
    let (y, u) = (ws.y.as_slice(), ws.qdd.as_slice());
    for (k, &(lo, hi)) in ws.support.iter().enumerate() {
        ws.r[k] = ws.b[k] - dot_unrolled(&y[k * nv + lo..k * nv + hi], &u[lo..hi]);
    }
    min_norm_solve(set, ws, allow_inconsistent)?;
    // u + Y λ (q̈ once the caller's solve with Wᵀ is done), generalized force Jᵀλ.
    mat_vec(&ws.y, ws.lambda.as_slice(), ws.tmp.as_mut_slice());
    ws.qdd += &ws.tmp;
    mat_tr_vec(
        &cd.j,
        ws.lambda.as_slice(),
        ws.generalized_force.as_mut_slice(),
    );
    Ok(())
}

/// The lower triangle of S = Yᵀ Y (all that the Cholesky factor reads), each entry summed over
/// the overlap of its two columns' non-zero ranges: two feet overlap on the base's rows only.
fn schur_lower(ws: &mut KktWorkspace, nv: usize, nc: usize) {
    let y = ws.y.as_slice();
    for a in 0..nc {
        for b in a..nc {
            let (lo, hi) = (
                ws.support[a].0.max(ws.support[b].0),
                ws.support[a].1.min(ws.support[b].1),
            );
            ws.s[(b, a)] = if lo < hi {
                dot_unrolled(&y[a * nv + lo..a * nv + hi], &y[b * nv + lo..b * nv + hi])
            } else {
                0.0
            };
        }
    }
}

/// Minimum-norm λ = S⁺ r of S λ = r (`linalg::MinNormSolver`: a Cholesky factor of S pivoted
/// where a row's pivot is not above `RANK_TOL_PIVOT` relative; S⁻¹ r when none is). The part of r
/// outside range(S) is the rows' inconsistency: an error where it is more than rounding
/// ([`disagree_beyond_rounding`] against r) unless `allow_inconsistent`. λ = S⁺ r varies
/// smoothly with the state whichever independent set was picked. Allocation-free (only the
/// error message allocates).
pub(super) fn min_norm_solve(
    set: &ConstraintSet,
    ws: &mut KktWorkspace,
    allow_inconsistent: bool,
) -> Result<()> {
    let nc = set.nrows;
    let rank = ws.min_norm.solve(
        &ws.s,
        ws.r.as_slice(),
        RANK_TOL_PIVOT,
        ws.lambda.as_mut_slice(),
    );
    if rank == nc {
        // Regular S: every right side is met (inconsistency and deficiency stay 0).
        return Ok(());
    }
    let (mut worst, mut inconsistency) = (0, 0.0);
    for k in 0..nc {
        let d = (ws.r[k] - ws.min_norm.r_hat[k]).abs();
        if d > inconsistency {
            (worst, inconsistency) = (k, d);
        }
    }
    ws.inconsistency = inconsistency;
    if disagree_beyond_rounding(inconsistency, ws.r.amax()) && !allow_inconsistent {
        let name = set
            .ranges
            .iter()
            .position(|rg| rg.contains(&worst))
            .map(|k| set.names[k].clone());
        return Err(Error::InconsistentConstraints {
            message: format!(
                "the constraint accelerations cannot all be met (rank {rank} of {nc}; largest \
                 violation {inconsistency:.3e} on a row of '{}')",
                name.unwrap_or_default()
            ),
        });
    }
    ws.rank_deficiency = nc - rank;
    Ok(())
}
