//! One step of each integrator on the configuration Lie group. The state is (q, v): q on the
//! group (nq), v in R^nv. For a stage, `Θ` is the tangent increment from q_n (so `q = q_n ⊕ Θ`),
//! and a stage derivative is `k = (dexp⁻¹_{−Θ}(v), q̈)` ∈ R^{2nv}.

use super::lie::dexp_inv;
use crate::error::{Error, Result};
use crate::model::Model;
use serde::{Deserialize, Serialize};

/// The integration method a scene or request chooses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Semi-implicit (symplectic) Euler: v⁺ = v + dt q̈(q, v), q⁺ = q ⊕ dt v⁺. Order 1.
    SemiImplicitEuler,
    /// Classical Runge–Kutta, order 4 (Munthe-Kaas on the group).
    #[default]
    Rk4,
    /// Dormand–Prince 5(4), adaptive with rtol/atol and an error estimate.
    Dopri5,
    /// Alexander's 2-stage L-stable SDIRK (order 2) with simplified Newton: for stiff scenes.
    Sdirk2,
}

impl Method {
    /// Explicit methods' stability limit of dt·|λ| on the imaginary axis (oscillators).
    pub fn explicit_stability_limit(self) -> Option<f64> {
        match self {
            Method::SemiImplicitEuler => Some(2.0),
            Method::Rk4 => Some(2.8),
            Method::Dopri5 | Method::Sdirk2 => None,
        }
    }
}

/// Butcher tableau of an explicit method (`b_hat` for the embedded error estimate).
pub struct Tableau {
    pub a: &'static [&'static [f64]],
    pub b: &'static [f64],
    pub b_hat: Option<&'static [f64]>,
    pub c: &'static [f64],
}

pub const RK4: Tableau = Tableau {
    a: &[&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]],
    b: &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
    b_hat: None,
    c: &[0.0, 0.5, 0.5, 1.0],
};

pub const DOPRI5: Tableau = Tableau {
    a: &[
        &[],
        &[1.0 / 5.0],
        &[3.0 / 40.0, 9.0 / 40.0],
        &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
        &[
            19372.0 / 6561.0,
            -25360.0 / 2187.0,
            64448.0 / 6561.0,
            -212.0 / 729.0,
        ],
        &[
            9017.0 / 3168.0,
            -355.0 / 33.0,
            46732.0 / 5247.0,
            49.0 / 176.0,
            -5103.0 / 18656.0,
        ],
        &[
            35.0 / 384.0,
            0.0,
            500.0 / 1113.0,
            125.0 / 192.0,
            -2187.0 / 6784.0,
            11.0 / 84.0,
        ],
    ],
    b: &[
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
        0.0,
    ],
    b_hat: Some(&[
        5179.0 / 57600.0,
        0.0,
        7571.0 / 16695.0,
        393.0 / 640.0,
        -92097.0 / 339200.0,
        187.0 / 2100.0,
        1.0 / 40.0,
    ]),
    c: &[0.0, 0.2, 0.3, 0.8, 8.0 / 9.0, 1.0, 1.0],
};

/// q̈ = f(t, q, v).
pub trait Accel {
    fn accel(&mut self, t: f64, q: &[f64], v: &[f64], qdd: &mut [f64]) -> Result<()>;
}

/// Stage state from the increment `dx = (Θ, Δv)`: q = q_n ⊕ Θ, v = v_n + Δv.
fn stage(model: &Model, q: &[f64], v: &[f64], dx: &[f64], qs: &mut [f64], vs: &mut [f64]) {
    let nv = v.len();
    model.integrate(q, &dx[..nv], 1.0, qs);
    for i in 0..nv {
        vs[i] = v[i] + dx[nv + i];
    }
}

/// Stage derivative k = (dexp⁻¹_{−Θ}(v_s), q̈(q_s, v_s)).
fn derivative<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    theta: &[f64],
    qs: &[f64],
    vs: &[f64],
    k: &mut [f64],
) -> Result<()> {
    let nv = vs.len();
    dexp_inv(model, theta, vs, &mut k[..nv]);
    f.accel(t, qs, vs, &mut k[nv..])
}

/// One explicit RK step; returns the embedded error vector (‖·‖ per component) if the tableau has one.
pub fn explicit_step<F: Accel>(
    f: &mut F,
    model: &Model,
    tab: &Tableau,
    t: f64,
    dt: f64,
    q: &mut [f64],
    v: &mut [f64],
) -> Result<Option<Vec<f64>>> {
    let (nq, nv) = (q.len(), v.len());
    let s = tab.b.len();
    let mut ks = vec![vec![0.0; 2 * nv]; s];
    let (mut qs, mut vs, mut dx) = (vec![0.0; nq], vec![0.0; nv], vec![0.0; 2 * nv]);
    for i in 0..s {
        dx.iter_mut().for_each(|x| *x = 0.0);
        for (j, &a) in tab.a[i].iter().enumerate() {
            for (d, k) in dx.iter_mut().zip(&ks[j]) {
                *d += dt * a * k;
            }
        }
        stage(model, q, v, &dx, &mut qs, &mut vs);
        derivative(f, model, t + tab.c[i] * dt, &dx[..nv], &qs, &vs, &mut ks[i])?;
    }
    dx.iter_mut().for_each(|x| *x = 0.0);
    for (k, &b) in ks.iter().zip(tab.b) {
        for (d, kk) in dx.iter_mut().zip(k) {
            *d += dt * b * kk;
        }
    }
    let err = tab.b_hat.map(|bh| {
        let mut e = vec![0.0; 2 * nv];
        for (k, (&b, &b2)) in ks.iter().zip(tab.b.iter().zip(bh)) {
            for (ee, kk) in e.iter_mut().zip(k) {
                *ee += dt * (b - b2) * kk;
            }
        }
        e
    });
    let (q0, v0) = (q.to_vec(), v.to_vec());
    stage(model, &q0, &v0, &dx, q, v);
    Ok(err)
}

/// Semi-implicit Euler step.
pub fn semi_implicit_euler_step<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    dt: f64,
    q: &mut [f64],
    v: &mut [f64],
) -> Result<()> {
    let mut a = vec![0.0; v.len()];
    f.accel(t, q, v, &mut a)?;
    for i in 0..v.len() {
        v[i] += dt * a[i];
    }
    let q0 = q.to_vec();
    model.integrate(&q0, v, dt, q);
    Ok(())
}

/// Alexander's L-stable SDIRK2 (γ = 1 − 1/√2) with a simplified Newton iteration whose Jacobian
/// `I − dt γ ∂k/∂x` comes from finite differences of q̈ at the step's start.
pub fn sdirk2_step<F: Accel>(
    f: &mut F,
    model: &Model,
    t: f64,
    dt: f64,
    q: &mut [f64],
    v: &mut [f64],
) -> Result<()> {
    let g = 1.0 - std::f64::consts::FRAC_1_SQRT_2;
    let (a, c) = ([[g, 0.0], [1.0 - g, g]], [g, 1.0]);
    let (nq, nv) = (q.len(), v.len());
    let n = 2 * nv;
    // ∂q̈/∂(Θ, v) at (q_n, v_n) by forward differences.
    let mut a0 = vec![0.0; nv];
    f.accel(t, q, v, &mut a0)?;
    let mut jac = nalgebra::DMatrix::<f64>::zeros(n, n);
    let (mut qs, mut vs, mut dx, mut ap) =
        (vec![0.0; nq], vec![0.0; nv], vec![0.0; n], vec![0.0; nv]);
    for col in 0..n {
        dx.iter_mut().for_each(|x| *x = 0.0);
        let scale = if col < nv {
            1.0
        } else {
            v[col - nv].abs().max(1.0)
        };
        let eps = 1e-7 * scale;
        dx[col] = eps;
        stage(model, q, v, &dx, &mut qs, &mut vs);
        f.accel(t, &qs, &vs, &mut ap)?;
        for r in 0..nv {
            jac[(nv + r, col)] = (ap[r] - a0[r]) / eps;
        }
        if col >= nv {
            jac[(col - nv, col)] = 1.0; // ∂(stage velocity)/∂v
        }
    }
    let iter_m = nalgebra::DMatrix::<f64>::identity(n, n) - jac * (dt * g);
    let lu = iter_m.lu();
    let mut ks = [vec![0.0; n], vec![0.0; n]];
    ks[0][..nv].copy_from_slice(v);
    ks[0][nv..].copy_from_slice(&a0);
    for i in 0..2 {
        if i == 1 {
            ks[1] = ks[0].clone();
        }
        let mut converged = false;
        for _ in 0..20 {
            for (d, idx) in dx.iter_mut().zip(0..n) {
                *d = dt * (0..=i).map(|j| a[i][j] * ks[j][idx]).sum::<f64>();
            }
            stage(model, q, v, &dx, &mut qs, &mut vs);
            let mut kf = vec![0.0; n];
            derivative(f, model, t + c[i] * dt, &dx[..nv], &qs, &vs, &mut kf)?;
            let resid = nalgebra::DVector::from_fn(n, |r, _| kf[r] - ks[i][r]);
            let delta = lu.solve(&resid).ok_or_else(|| Error::StepTooLarge {
                message: "SDIRK2 Newton matrix is singular".into(),
            })?;
            let scale = ks[i].iter().fold(1.0f64, |m, x| m.max(x.abs()));
            for r in 0..n {
                ks[i][r] += delta[r];
            }
            if delta.amax() <= 1e-10 * scale {
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
    for (d, idx) in dx.iter_mut().zip(0..n) {
        *d = dt * ((1.0 - g) * ks[0][idx] + g * ks[1][idx]);
    }
    let (q0, v0) = (q.to_vec(), v.to_vec());
    stage(model, &q0, &v0, &dx, q, v);
    Ok(())
}
