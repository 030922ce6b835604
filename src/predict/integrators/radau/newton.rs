//! The simplified Newton iteration of a Radau IIA step on its stage increments: the Jacobian
//! J = ∂k/∂x at x_n, the Newton matrix block-diagonalised by A⁻¹ = T Λ T⁻¹ into one real and
//! one complex shifted system, each reduced to the velocities' nv rows and factored, the
//! starting values, and one update of the transformed stages W = T⁻¹ Z.

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

/// Factors the Newton systems `(γ/h) I − J` and `σ I − J`, σ = (α − iβ)/h (the complex pair: its
/// real 2n × 2n form is [[α/h − J, β/h], [−β/h, α/h − J]]), each through its Schur complement on
/// the velocity rows, as RADAU5 does for second-order systems (its M1 option, Hairer & Wanner
/// IV.8). The real one is `(γ/h)(I − (h/γ) J)`, the linearly implicit steps' `ShiftedFactor`
/// (shifted.rs). The complex one is its counterpart for a complex shift: J = [[0, I], [J_q, J_v]],
/// so `(σ I − J) (x, y) = (r, p)` gives x = (r + y)/σ and `(σ² I − σ J_v − J_q) y = σ p + J_q r`,
/// an nv × nv complex system factored in its real 2nv × 2nv form [[S_r, −S_i], [S_i, S_r]].
/// Together 8 times fewer operations than the full forms.
pub(super) fn factor(ws: &mut RadauWorkspace, h: f64) -> Result<()> {
    let nv = ws.jac.nrows() / 2;
    let (al, be) = (ws.co.alpha / h, ws.co.beta / h);
    for c in 0..nv {
        for r in 0..nv {
            let (jq, jv) = (ws.jac[(nv + r, c)], ws.jac[(nv + r, nv + c)]);
            let diag = if r == c { 1.0 } else { 0.0 };
            // σ² = α² − β² − 2iαβ; −σ J_v = −α J_v + iβ J_v.
            let re = (al * al - be * be) * diag - al * jv - jq;
            let im = -2.0 * al * be * diag + be * jv;
            ws.e2[(r, c)] = re;
            ws.e2[(nv + r, nv + c)] = re;
            ws.e2[(r, nv + c)] = -im;
            ws.e2[(nv + r, c)] = im;
        }
    }
    if !(ws.e1.factor(&ws.jac, h / ws.co.gamma) && lu_in_place(&mut ws.e2, &mut ws.piv2)) {
        return Err(Error::StepTooLarge {
            message: format!("the Radau IIA Newton matrix is singular at h = {h} s"),
        });
    }
    ws.factor_h = h;
    Ok(())
}

/// `b ← ((γ/h) I − J)⁻¹ b` (n = 2nv) with the factor of [`factor`].
pub(super) fn solve_real(ws: &RadauWorkspace, b: &mut [f64]) {
    let g = ws.factor_h / ws.co.gamma;
    b.iter_mut().for_each(|x| *x *= g);
    ws.e1.solve(b);
}

/// `b ← (real form of σ I − J)⁻¹ b` (2n = 4nv: the real parts, then the imaginary ones, each
/// q rows then v rows) with the factor of [`factor`].
pub(super) fn solve_complex(ws: &mut RadauWorkspace, b: &mut [f64]) {
    let nv = ws.piv2.len() / 2;
    let h = ws.factor_h;
    let (al, be) = (ws.co.alpha / h, ws.co.beta / h);
    let (re, im) = b.split_at_mut(2 * nv);
    let ((r_re, p_re), (r_im, p_im)) = (re.split_at_mut(nv), im.split_at_mut(nv));
    let (jq_re, jq_im) = ws.jq_r.split_at_mut(nv);
    jq_times(&ws.jac, r_re, jq_re);
    jq_times(&ws.jac, r_im, jq_im);
    // The right-hand side σ p + J_q r, real parts then imaginary, solved in place of it.
    let y = &mut ws.y2;
    for k in 0..nv {
        y[k] = al * p_re[k] + be * p_im[k] + jq_re[k];
        y[nv + k] = al * p_im[k] - be * p_re[k] + jq_im[k];
    }
    lu_solve(&ws.e2, &ws.piv2, y);
    // x = (r + y)/σ = (r + y) σ̄ / |σ|².
    let norm = al * al + be * be;
    for k in 0..nv {
        let (w_re, w_im) = (r_re[k] + y[k], r_im[k] + y[nv + k]);
        r_re[k] = (al * w_re - be * w_im) / norm;
        r_im[k] = (be * w_re + al * w_im) / norm;
        p_re[k] = y[k];
        p_im[k] = y[nv + k];
    }
}

/// out = J_q r: J's lower-left nv × nv block times r.
fn jq_times(jac: &nalgebra::DMatrix<f64>, r: &[f64], out: &mut [f64]) {
    let nv = r.len();
    out.fill(0.0);
    for (c, &rc) in r.iter().enumerate() {
        if rc != 0.0 {
            let col = &jac.as_slice()[c * 2 * nv + nv..c * 2 * nv + 2 * nv];
            for (o, &j) in out.iter_mut().zip(col) {
                *o += j * rc;
            }
        }
    }
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
    let (mut r1, mut r2) = (std::mem::take(&mut ws.r1), std::mem::take(&mut ws.r2));
    solve_real(ws, &mut r1);
    solve_complex(ws, &mut r2);
    (ws.r1, ws.r2) = (r1, r2);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;
    use nalgebra::{Complex, DMatrix, DVector};

    /// The reduced solves against the full shifted systems solved by nalgebra's LU (the real one
    /// over 2nv rows, the complex one in complex arithmetic), for a stiff J at a step of 1 ms:
    /// achieved 4e-16 and 5e-16 of the solution.
    #[test]
    fn the_reduced_solves_match_the_full_shifted_systems() {
        let (nq, nv, h) = (7, 7, 1e-3);
        let mut rng = Rng(0x5eed);
        let mut ws = RadauWorkspace::new(nq, nv);
        ws.size_matrices(2 * nv);
        for i in 0..nv {
            ws.jac[(i, nv + i)] = 1.0;
            for j in 0..2 * nv {
                // Stiffness up to 1e6 /s², damping up to 1e3 /s.
                let scale = if j < nv { 1e6 } else { 1e3 };
                ws.jac[(nv + i, j)] = scale * rng.normal();
            }
        }
        factor(&mut ws, h).unwrap();
        let n = 2 * nv;
        let (g, al, be) = (ws.co.gamma / h, ws.co.alpha / h, ws.co.beta / h);

        let b: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let full = DMatrix::identity(n, n) * g - &ws.jac;
        let want = full.lu().solve(&DVector::from_vec(b.clone())).unwrap();
        let mut got = b;
        solve_real(&ws, &mut got);
        let err = (DVector::from_vec(got) - &want).amax() / want.amax();
        assert!(err < 1e-14, "real shift: relative error {err:e}");

        let b: Vec<f64> = (0..2 * n).map(|_| rng.normal()).collect();
        let sigma = Complex::new(al, -be);
        let jc = ws.jac.map(|x| Complex::new(x, 0.0));
        let full = DMatrix::identity(n, n) * sigma - jc;
        let rhs = DVector::from_fn(n, |k, _| Complex::new(b[k], b[n + k]));
        let want = full.lu().solve(&rhs).unwrap();
        let mut got = b;
        solve_complex(&mut ws, &mut got);
        let err = (0..n)
            .map(|k| (Complex::new(got[k], got[n + k]) - want[k]).norm())
            .fold(0.0, f64::max)
            / want.iter().map(|z| z.norm()).fold(0.0, f64::max);
        assert!(err < 1e-14, "complex shift: relative error {err:e}");
    }
}
