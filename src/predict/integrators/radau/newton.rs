//! The simplified Newton iteration of a Radau IIA step on its stage increments: the Jacobian
//! J = ∂k/∂x at x_n, the Newton matrix block-diagonalised by A⁻¹ = T Λ T⁻¹ and factored as one
//! real n × n and one real 2n × 2n system, the starting values, and one update of the
//! transformed stages W = T⁻¹ Z.

use super::RadauWorkspace;
use crate::error::{Error, Result};
use crate::linalg::{lu_in_place, lu_solve};
use crate::model::Model;
use crate::predict::integrators::{Accel, derivative, stage};
use nalgebra::{Matrix3, Vector3};

/// J = [[0, I], [∂q̈/∂q, ∂q̈/∂v]] at (t, q, v) (`ws.f0` holds k there).
pub(super) fn jacobian<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    q: &[f64],
    v: &[f64],
    ws: &mut RadauWorkspace,
) -> Result<()> {
    let nv = v.len();
    ws.jac.as_mut_slice().fill(0.0);
    for i in 0..nv {
        ws.jac[(i, nv + i)] = 1.0;
    }
    f.accel_jacobian(model, (t, q, v), &ws.f0[nv..], &mut ws.jac, &mut ws.scratch)?;
    ws.jacobians += 1;
    ws.jac_valid = true;
    ws.jac_fresh = true;
    ws.factor_h = f64::NAN;
    Ok(())
}

/// LU of γ/h − J and of the complex pair's real 2n × 2n form.
pub(super) fn factor(ws: &mut RadauWorkspace, h: f64) -> Result<()> {
    let n = ws.jac.nrows();
    let (g, al, be) = (ws.co.gamma / h, ws.co.alpha / h, ws.co.beta / h);
    for c in 0..n {
        for r in 0..n {
            let j = ws.jac[(r, c)];
            let diag = if r == c { 1.0 } else { 0.0 };
            ws.e1[(r, c)] = g * diag - j;
            ws.e2[(r, c)] = al * diag - j;
            ws.e2[(n + r, n + c)] = al * diag - j;
            ws.e2[(r, n + c)] = be * diag;
            ws.e2[(n + r, c)] = -be * diag;
        }
    }
    if !(lu_in_place(&mut ws.e1, &mut ws.piv1) && lu_in_place(&mut ws.e2, &mut ws.piv2)) {
        return Err(Error::StepTooLarge {
            message: format!("the Radau IIA Newton matrix is singular at h = {h} s"),
        });
    }
    ws.factor_h = h;
    Ok(())
}

/// Z⁰ from the last step's collocation polynomial extrapolated to this step's nodes (zero at the
/// first step), and W⁰ = T⁻¹ Z⁰.
pub(super) fn starting_values(ws: &mut RadauWorkspace, h: f64) {
    let n = ws.f0.len();
    let [c1, c2, _] = ws.co.c;
    for i in 0..3 {
        let s = ws.co.c[i] * h / ws.h_old;
        for k in 0..n {
            ws.z[i][k] = if ws.have_cont {
                let [a1, a2, a3] = [ws.cont[0][k], ws.cont[1][k], ws.cont[2][k]];
                s * (a1 + (s - (c2 - 1.0)) * (a2 + (s - (c1 - 1.0)) * a3))
            } else {
                0.0
            };
        }
    }
    let t_inv = ws.co.t_inv;
    apply3(&t_inv, &ws.z, &mut ws.w);
}

/// out_i = Σ_j m_ij x_j, per component (the stage transformations Z ↔ W).
fn apply3(m: &Matrix3<f64>, x: &[Vec<f64>; 3], out: &mut [Vec<f64>; 3]) {
    for k in 0..x[0].len() {
        let y = m * Vector3::new(x[0][k], x[1][k], x[2][k]);
        for i in 0..3 {
            out[i][k] = y[i];
        }
    }
}

/// F_i = k(x_n ⊕ Z_i) at t + c_i h; false when a stage state is not finite.
#[allow(clippy::too_many_arguments)]
pub(super) fn stage_derivatives<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    h: f64,
    q: &[f64],
    v: &[f64],
    ws: &mut RadauWorkspace,
) -> Result<bool> {
    let nv = v.len();
    for i in 0..3 {
        stage(model, q, v, &ws.z[i], &mut ws.qs, &mut ws.vs);
        if !ws.qs.iter().chain(&ws.vs).all(|x| x.is_finite()) {
            return Ok(false);
        }
        derivative(
            f,
            model,
            t + ws.co.c[i] * h,
            &ws.z[i][..nv],
            &ws.qs,
            &ws.vs,
            &mut ws.f[i],
        )?;
    }
    Ok(true)
}

/// One simplified Newton update of W: returns the scaled RMS norm of the correction.
pub(super) fn newton_update(ws: &mut RadauWorkspace, h: f64) -> f64 {
    let n = ws.f0.len();
    let (g, al, be) = (ws.co.gamma / h, ws.co.alpha / h, ws.co.beta / h);
    let ti = ws.co.t_inv;
    for k in 0..n {
        let fk = Vector3::new(ws.f[0][k], ws.f[1][k], ws.f[2][k]);
        let gk = ti * fk;
        let (w1, w2, w3) = (ws.w[0][k], ws.w[1][k], ws.w[2][k]);
        ws.r1[k] = gk[0] - g * w1;
        ws.r2[k] = gk[1] - al * w2 - be * w3;
        ws.r2[n + k] = gk[2] + be * w2 - al * w3;
    }
    lu_solve(&ws.e1, &ws.piv1, &mut ws.r1);
    lu_solve(&ws.e2, &ws.piv2, &mut ws.r2);
    let mut sum = 0.0;
    for k in 0..n {
        let d = [ws.r1[k], ws.r2[k], ws.r2[n + k]];
        for (i, di) in d.iter().enumerate() {
            ws.w[i][k] += di;
            sum += (di / ws.scal[k]).powi(2);
        }
    }
    (sum / (3 * n) as f64).sqrt()
}

/// Z = T W.
pub(super) fn transform_back(ws: &mut RadauWorkspace) {
    let t = ws.co.t;
    apply3(&t, &ws.w, &mut ws.z);
}
