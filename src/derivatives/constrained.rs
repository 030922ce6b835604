//! Derivatives of the constrained forward dynamics (multiplier form); the method is in the
//! module doc of [`crate::derivatives`].
//!
//! Constraint kinds with derivatives: point (both sides may move), coupling/mimic (constant
//! rows) and rolling. The others return [`Error::Unsupported`] naming the constraint.

use super::DerivativeData;
use super::aba::invert_factor;
use super::rnea::{body_variation_q, body_variation_v, rnea_derivatives_with_point_forces};
use super::rolling::RollingState;
use crate::algorithm::{Data, crba, point_position};
use crate::constraints::{Constraint, ConstraintData, ConstraintSet, PointConstraint};
use crate::dynamics::{Baumgarte, KktWorkspace, constrained_forward_dynamics};
use crate::error::{Error, Result};
use crate::linalg::{gemm_into, gemm_tr_into, semidefinite_cholesky, semidefinite_solve};
use crate::model::Model;
use nalgebra::Vector3;

/// Rank test of J M⁻¹ Jᵀ: a row whose Cholesky pivot is below this fraction of the largest
/// diagonal is dependent. Looser than the multiplier solve's first attempt (1e-12): an exactly
/// dependent row's pivot is rounding times the condition number, and 1e-12 missed the
/// dependent wheel row of a floating mobile manipulator state (tests/derivatives_fd.rs); 1e-9
/// still keeps rows at a singular-value ratio above ~3e-5.
const RANK_TOL: f64 = 1e-9;

/// Solves the constrained dynamics at (q, v, τ) (q̈ in `ws.qdd` and `dd.qdd`, λ in
/// `ws.lambda`) and writes ∂q̈/∂(q, v, τ) into `dd.dqdd_dq`, `dd.dqdd_dv`, `dd.dqdd_dtau` and
/// ∂λ/∂(q, v, τ) into `dd.dlambda_dq`, `dd.dlambda_dv`, `dd.dlambda_dtau`. `dd` must be sized
/// for `set.nrows` rows.
#[allow(clippy::too_many_arguments)]
pub fn constrained_dynamics_derivatives(
    model: &Model,
    data: &mut Data,
    set: &ConstraintSet,
    cd: &mut ConstraintData,
    ws: &mut KktWorkspace,
    dd: &mut DerivativeData,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    stab: Baumgarte,
) -> Result<()> {
    let nc = set.nrows;
    if dd.dlambda_dq.nrows() != nc {
        return Err(Error::Dimension {
            what: "DerivativeData constraint rows".into(),
            expected: nc,
            got: dd.dlambda_dq.nrows(),
        });
    }
    for (k, c) in set.items.iter().enumerate() {
        if !matches!(
            c,
            Constraint::Point(_) | Constraint::Coupling(_) | Constraint::Rolling(_)
        ) {
            return Err(Error::Unsupported {
                what: format!("derivatives of constraint '{}'", set.names[k]),
                why: format!(
                    "kind {} has no analytic derivatives yet (point, coupling/mimic and rolling have)",
                    c.kind()
                ),
            });
        }
    }
    constrained_forward_dynamics(model, data, set, cd, ws, q, v, tau, stab)?;
    dd.qdd.copy_from(&ws.qdd);

    // λ as point forces on the bodies (the kinematics of the solve are still in `data`).
    dd.clear_point_forces();
    for (k, c) in set.items.iter().enumerate() {
        if let Constraint::Point(pc) = c {
            let f = point_force(pc, &ws.lambda.as_slice()[set.ranges[k].clone()]);
            let (ba, bb) = (model.frames[pc.frame_a].body, model.frames[pc.frame_b].body);
            if ba > 0 {
                let pa = point_position(model, data, pc.frame_a, &pc.point_a);
                dd.add_point_force(ba, &pa, &f);
            }
            if bb > 0 {
                let pb = point_position(model, data, pc.frame_b, &pc.point_b);
                dd.add_point_force(bb, &pb, &-f);
            }
        }
        if let Constraint::Rolling(rc) = c {
            let f = rolling_force(rc, &ws.lambda.as_slice()[set.ranges[k].clone()]);
            let st = RollingState::new(model, data, dd, rc);
            dd.add_point_force(st.body, &st.pc, &f);
        }
    }
    let qdd = std::mem::take(&mut dd.qdd);
    rnea_derivatives_with_point_forces(model, data, dd, q, v, qdd.as_slice());
    dd.qdd = qdd;
    rolling_contact_motion(model, data, set, ws.lambda.as_slice(), dd);
    crba(model, data, q);
    invert_mass_or_augmented(model, data, cd, dd)?;
    constraint_row_derivatives(model, data, set, cd, dd, stab);
    solve_kkt_derivatives(cd, dd);
    Ok(())
}

/// M⁻¹ into `dd.minv`, or — when only the constraints give some coordinate inertia, as in
/// the multiplier solve — the inverse of M + ρ JᵀJ (ρ = max(1, max diag M)), which the KKT
/// system admits as well: `(M + ρJᵀJ) q̈ − Jᵀλ = R₁ + ρ Jᵀ R₂` with `J q̈ = R₂`.
fn invert_mass_or_augmented(
    model: &Model,
    data: &Data,
    cd: &ConstraintData,
    dd: &mut DerivativeData,
) -> Result<()> {
    let nv = model.nv;
    let m = &data.mass_matrix;
    dd.rho = 0.0;
    dd.chol.view_mut((0, 0), (nv, nv)).copy_from(m);
    if invert_factor(nv, dd).is_ok() {
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

/// The world force of a point constraint's rows: Σ λ_r e_axis(r).
fn point_force(pc: &PointConstraint, lambda: &[f64]) -> Vector3<f64> {
    let mut f = Vector3::zeros();
    for (r, &ax) in pc.axes.iter().enumerate() {
        f[ax] += lambda[r];
    }
    f
}

/// The world force of a rolling contact's rows: Σ λ_r t_row(r).
fn rolling_force(rc: &crate::constraints::RollingConstraint, lambda: &[f64]) -> Vector3<f64> {
    let mut f = Vector3::zeros();
    for (r, &row) in rc.rows.iter().enumerate() {
        f += rc.basis.column(row) * lambda[r];
    }
    f
}

/// A rolling contact force acts at p_c, which slides over the rim instead of moving with the
/// wheel: RNEA's point-force term moved it as a material point, so add the generalized force
/// of f at the difference δ = dp_c − (S_lin + S_ang × p_c) = r (du − S_ang × u) to every
/// coordinate above the wheel, for the columns that move the wheel.
fn rolling_contact_motion(
    model: &Model,
    data: &Data,
    set: &ConstraintSet,
    lambda: &[f64],
    dd: &mut DerivativeData,
) {
    for (k, c) in set.items.iter().enumerate() {
        let Constraint::Rolling(rc) = c else { continue };
        let f = rolling_force(rc, &lambda[set.ranges[k].clone()]);
        let st = RollingState::new(model, data, dd, rc);
        for j in 0..model.nv {
            let body_j = dd.dof_body[j];
            if st.body < body_j || st.body >= dd.subtree_end[body_j] {
                continue;
            }
            let s = dd.o_s[j];
            let delta = st.contact_variation(&s) - s.lin - s.ang.cross(&st.pc);
            let moment = delta.cross(&f);
            let mut b = st.body;
            while b > 0 {
                let jb = &model.bodies[b].joint;
                for c in 0..jb.kind.nv() {
                    let i = jb.idx_v + c;
                    dd.dtau_dq[(i, j)] -= dd.o_s[i].ang.dot(&moment);
                }
                b = model.bodies[b].parent;
            }
        }
    }
}

/// ∂/∂q and ∂/∂v of the acceleration-level rows `J q̈ + γ + K_d J v + K_p φ` at fixed q̈ into
/// `dd.rows_dq`, `dd.rows_dv` (uses the world kinematics of the last RNEA pass at q̈).
fn constraint_row_derivatives(
    model: &Model,
    data: &Data,
    set: &ConstraintSet,
    cd: &ConstraintData,
    dd: &mut DerivativeData,
    stab: Baumgarte,
) {
    dd.rows_dq.fill(0.0);
    dd.rows_dv.fill(0.0);
    for (k, c) in set.items.iter().enumerate() {
        let rows = set.ranges[k].clone();
        match c {
            Constraint::Point(pc) => {
                for (side, frame, point) in [
                    (1.0, pc.frame_a, &pc.point_a),
                    (-1.0, pc.frame_b, &pc.point_b),
                ] {
                    let body = model.frames[frame].body;
                    if body == 0 {
                        continue;
                    }
                    let p = point_position(model, data, frame, point);
                    for j in 0..model.nv {
                        let body_j = dd.dof_body[j];
                        if body < body_j || body >= dd.subtree_end[body_j] {
                            continue;
                        }
                        let (dq, dv) = point_variations(model, dd, body, &p, j, stab);
                        for (r, &ax) in pc.axes.iter().enumerate() {
                            dd.rows_dq[(rows.start + r, j)] += side * dq[ax];
                            dd.rows_dv[(rows.start + r, j)] += side * dv[ax];
                        }
                    }
                }
            }
            // Constant rows: γ = 0 and J v, φ linear, so only K_p φ and K_d J v vary.
            Constraint::Coupling(_) => {
                for r in rows {
                    for j in 0..model.nv {
                        dd.rows_dq[(r, j)] = stab.kp * cd.j[(r, j)];
                        dd.rows_dv[(r, j)] = stab.kd * cd.j[(r, j)];
                    }
                }
            }
            Constraint::Rolling(rc) => {
                let st = RollingState::new(model, data, dd, rc);
                for j in 0..model.nv {
                    let s = dd.o_s[j];
                    if let Some((dv, da)) = body_variation_q(model, dd, st.body, j) {
                        let var = st.by_q(dd, &s, &dv, &da, stab.kd);
                        for (r, &row) in rc.rows.iter().enumerate() {
                            let dir = rc.basis.column(row);
                            let mut x = dir.dot(&var.g_plus_kd_v);
                            if row == 2 {
                                x += stab.kp * var.phi_n;
                            }
                            dd.rows_dq[(rows.start + r, j)] = x;
                        }
                    }
                    if let Some((_, da)) = body_variation_v(model, dd, st.body, j) {
                        let var = st.by_v(dd, &s, &da, stab.kd);
                        for (r, &row) in rc.rows.iter().enumerate() {
                            dd.rows_dv[(rows.start + r, j)] = rc.basis.column(row).dot(&var);
                        }
                    }
                }
            }
            _ => unreachable!("checked by constrained_dynamics_derivatives"),
        }
    }
}

/// Variation along q-column j and along v_j of `p̈ + K_d ṗ + K_p p` for the material point at
/// world position `p` of `body` (in j's subtree): p̈ = a₀ + α × p + ω × ṗ, ṗ = v₀ + ω × p with
/// the body's world twist (v₀, ω) and true spatial acceleration (a₀, α).
fn point_variations(
    model: &Model,
    dd: &DerivativeData,
    body: usize,
    p: &Vector3<f64>,
    j: usize,
    stab: Baumgarte,
) -> (Vector3<f64>, Vector3<f64>) {
    let s = dd.o_s[j];
    let (vk, ak) = (dd.o_v[body], dd.o_a[body]);
    let w = vk.ang;
    let pd = vk.lin + w.cross(p);
    let alpha = ak.ang;

    // Along δ_j: the subtree moves by S.
    let (dv, da) = body_variation_q(model, dd, body, j).expect("body in j's subtree");
    let dp = s.lin + s.ang.cross(p);
    let dpd = dv.lin + dv.ang.cross(p) + w.cross(&dp);
    let dpdd = da.lin + da.ang.cross(p) + alpha.cross(&dp) + dv.ang.cross(&pd) + w.cross(&dpd);
    let by_q = dpdd + dpd * stab.kd + dp * stab.kp;

    // Along v_j.
    let (_, da) = body_variation_v(model, dd, body, j).expect("body in j's subtree");
    let dpd = s.lin + s.ang.cross(p);
    let dpdd = da.lin + da.ang.cross(p) + s.ang.cross(&pd) + w.cross(&dpd);
    let by_v = dpdd + dpd * stab.kd;
    (by_q, by_v)
}

/// Solves the differentiated KKT system for the three inputs through M⁻¹ and
/// K = J M⁻¹ Jᵀ: K ∂λ = R₂ − J M⁻¹ R₁, ∂q̈ = M⁻¹ (R₁ + Jᵀ ∂λ) (M⁻¹ of the augmented M and
/// R₁ + ρ Jᵀ R₂ when ρ > 0).
fn solve_kkt_derivatives(cd: &ConstraintData, dd: &mut DerivativeData) {
    let j = &cd.j;
    // M⁻¹Jᵀ by columns (M⁻¹ is symmetric), without forming Jᵀ.
    for c in 0..j.nrows() {
        for i in 0..j.ncols() {
            dd.minv_jt[(i, c)] = (0..j.ncols()).map(|k| dd.minv[(i, k)] * j[(c, k)]).sum();
        }
    }
    gemm_into(&mut dd.schur, 1.0, j, &dd.minv_jt, 0.0);
    let rank = semidefinite_cholesky(&mut dd.schur, RANK_TOL, &mut dd.dropped);
    dd.lambda_unique = rank == j.nrows();
    null_space_of_schur(j, dd);

    // q: R₁ = −∂(RNEA − Jᵀλ)/∂q, R₂ = −rows_dq.
    dd.r1.copy_from(&dd.dtau_dq);
    dd.r1.neg_mut();
    gemm_tr_into(&mut dd.r1, -dd.rho, j, &dd.rows_dq, 1.0);
    gemm_into(&mut dd.rhs_v, 1.0, &dd.minv, &dd.r1, 0.0);
    gemm_into(&mut dd.rhs_c, -1.0, j, &dd.rhs_v, 0.0);
    dd.rhs_c -= &dd.rows_dq;
    solve_columns(dd, Input::Q);
    // v
    dd.r1.copy_from(&dd.dtau_dv);
    dd.r1.neg_mut();
    gemm_tr_into(&mut dd.r1, -dd.rho, j, &dd.rows_dv, 1.0);
    gemm_into(&mut dd.rhs_v, 1.0, &dd.minv, &dd.r1, 0.0);
    gemm_into(&mut dd.rhs_c, -1.0, j, &dd.rhs_v, 0.0);
    dd.rhs_c -= &dd.rows_dv;
    solve_columns(dd, Input::V);
    // τ: R₁ = 1, R₂ = 0.
    dd.rhs_v.copy_from(&dd.minv);
    gemm_into(&mut dd.rhs_c, -1.0, j, &dd.rhs_v, 0.0);
    solve_columns(dd, Input::Tau);
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
        dropped,
        rhs_c,
        rhs_v,
        minv_jt,
        null_basis,
        n_null,
        ..
    } = dd;
    for c in 0..rhs_c.ncols() {
        for k in 0..*n_null {
            let dot = null_basis.column(k).dot(&rhs_c.column(c));
            for r in 0..rhs_c.nrows() {
                rhs_c[(r, c)] -= dot * null_basis[(r, k)];
            }
        }
        semidefinite_solve(schur, dropped, rhs_c.column_mut(c).as_mut_slice());
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
        dlambda.fill(0.0);
    }
}
