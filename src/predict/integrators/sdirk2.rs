//! Alexander's L-stable two-stage SDIRK (γ = 1 − 1/√2), for stiff scenes where an explicit
//! step would have to be tiny: the stages solved by a simplified Newton iteration on the
//! configuration Lie group, with the buffers of the shared [`StepWorkspace`] (integrators/mod.rs).

use crate::error::{Error, Result};
use crate::model::Model;
use crate::predict::IntegrationSettings;
use crate::predict::integrators::radau::RadauWorkspace;
use crate::predict::integrators::{
    Accel, StepOutcome, StepWorkspace, derivative, factor_shifted, stage, state_jacobian,
};

/// Alexander's L-stable SDIRK2 (γ = 1 − 1/√2) with a simplified Newton iteration on
/// `(I − dt γ ∂k/∂x) δ = k(x) − k`. The Jacobian (analytic, or finite differences of q̈) is
/// kept from step to step while Newton converges in ≤ 6 iterations and recomputed at the step's
/// start state when Newton fails or slows down; a dt that differs by more than rounding
/// (relative 1e-6: sample spans of slightly different length) only refactors the matrix, which
/// costs no evaluation (comparing dt bit for bit would refresh the Jacobian at most steps).
pub fn sdirk2_step<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    dt: f64,
    q: &mut [f64],
    v: &mut [f64],
    ws: &mut StepWorkspace,
) -> Result<()> {
    let g = 1.0 - std::f64::consts::FRAC_1_SQRT_2;
    f.accel(t, q, v, &mut ws.a0)?;
    ws.jac_fresh = false;
    if !ws.jac_valid {
        state_jacobian(f, model, t, q, v, ws)?;
        factor_shifted(ws, dt * g, "SDIRK2 Newton")?;
        ws.newton_dt = dt;
    } else if (dt - ws.newton_dt).abs() > 1e-6 * ws.newton_dt {
        factor_shifted(ws, dt * g, "SDIRK2 Newton")?;
        ws.newton_dt = dt;
    }
    loop {
        match sdirk2_stages(f, model, t, dt, q, v, ws) {
            Ok(iterations) => {
                // Slow convergence: a fresh Jacobian next step.
                ws.jac_valid = iterations <= 6;
                break;
            }
            Err(e) if ws.jac_fresh => return Err(e),
            Err(_) => {
                // A stale Jacobian: refresh it at this state and try once more.
                state_jacobian(f, model, t, q, v, ws)?;
                factor_shifted(ws, dt * g, "SDIRK2 Newton")?;
                ws.newton_dt = dt;
            }
        }
    }
    for i in 0..ws.dx.len() {
        ws.dx[i] = dt * ((1.0 - g) * ws.ks[0][i] + g * ws.ks[1][i]);
    }
    ws.save(q, v);
    stage(model, &ws.q0, &ws.v0, &ws.dx, q, v);
    Ok(())
}

/// The two implicit stages k_i = k(q_n ⊕ dt Σ_j a_ij k_j) into ks[0], ks[1]; returns the
/// largest number of Newton iterations a stage needed.
fn sdirk2_stages<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    dt: f64,
    q: &[f64],
    v: &[f64],
    ws: &mut StepWorkspace,
) -> Result<usize> {
    let g = 1.0 - std::f64::consts::FRAC_1_SQRT_2;
    let (a, c) = ([[g, 0.0], [1.0 - g, g]], [g, 1.0]);
    let nv = v.len();
    let n = 2 * nv;
    ws.ks[0][..nv].copy_from_slice(v);
    ws.ks[0][nv..n].copy_from_slice(&ws.a0);
    let mut most = 0;
    for i in 0..2 {
        if i == 1 {
            let (k0, k1) = ws.ks.split_at_mut(1);
            k1[0].copy_from_slice(&k0[0]);
        }
        let mut converged = false;
        for it in 1..=20 {
            most = most.max(it);
            for idx in 0..n {
                ws.dx[idx] = dt * (0..=i).map(|j| a[i][j] * ws.ks[j][idx]).sum::<f64>();
            }
            stage(model, q, v, &ws.dx, &mut ws.qs, &mut ws.vs);
            if !ws.qs.iter().chain(&ws.vs).all(|x| x.is_finite()) {
                break; // the iteration diverged: not converged, StepTooLarge below
            }
            // k(x) into the error buffer (unused by SDIRK2), then the residual k(x) − k_i.
            derivative(
                f,
                model,
                t + c[i] * dt,
                &ws.dx[..nv],
                &ws.qs,
                &ws.vs,
                &mut ws.err,
            )?;
            for r in 0..n {
                ws.resid[r] = ws.err[r] - ws.ks[i][r];
            }
            ws.newton.solve(&mut ws.resid);
            let scale = ws.ks[i].iter().fold(1.0f64, |m, x| m.max(x.abs()));
            let mut step = 0.0f64;
            for r in 0..n {
                ws.ks[i][r] += ws.resid[r];
                step = step.max(ws.resid[r].abs());
            }
            if !step.is_finite() {
                break;
            }
            if step <= 1e-10 * scale {
                converged = true;
                break;
            }
        }
        if !converged {
            return Err(Error::StepTooLarge {
                message: format!(
                    "SDIRK2 Newton iteration did not converge at t = {t} s with dt = {dt} s"
                ),
            });
        }
    }
    Ok(most)
}

/// Alexander's two-stage L-stable SDIRK.
pub struct Sdirk2;

impl super::Integrator for Sdirk2 {
    fn method(&self) -> super::Method {
        super::Method::Sdirk2
    }
    fn order(&self) -> u32 {
        2
    }
    /// Newton iterations per stage vary: counted while running.
    fn evaluations_per_step(&self) -> Option<f64> {
        None
    }
    fn is_adaptive(&self) -> bool {
        false
    }
    fn is_implicit(&self) -> bool {
        true
    }
    fn stability_limit(&self) -> Option<f64> {
        None
    }
    fn linearized_as(&self) -> Option<super::Method> {
        None
    }
}

impl super::Step for Sdirk2 {
    fn step<F: Accel>(
        &self,
        f: &mut F,
        model: &Model,
        (t, dt): (f64, f64),
        q: &mut [f64],
        v: &mut [f64],
        ws: &mut StepWorkspace,
        _: &mut RadauWorkspace,
        _: &IntegrationSettings,
    ) -> Result<Option<StepOutcome>> {
        sdirk2_step(f, model, t, dt, q, v, ws)?;
        Ok(None)
    }
}
