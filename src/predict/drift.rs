//! Drift control after a step: mass-weighted projection of q onto φ(q) = 0 (Newton, holonomic
//! rows only) and of v onto J(q) v = 0 (Ascher, Chin, Petzold & Reich 1995):
//!   Δq = −M⁻¹ Jₕᵀ (Jₕ M⁻¹ Jₕᵀ)⁺ φₕ,  q ← q ⊕ Δq   (repeated while |φ| > tol),
//!   v ← v − M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁺ J v.

use crate::algorithm::crba;
use crate::error::{Error, Result};
use crate::system::System;
use nalgebra::{DMatrix, DVector};

/// Position tolerance of the Newton projection [m or rad].
pub const POSITION_TOL: f64 = 1e-12;

/// `M⁻¹ Aᵀ (A M⁻¹ Aᵀ)⁺ r` for the rows of A (pseudo-inverse through SVD, redundant rows allowed).
fn weighted_correction(
    m: &DMatrix<f64>,
    a: &DMatrix<f64>,
    r: &DVector<f64>,
) -> Option<DVector<f64>> {
    let chol = m.clone().cholesky()?;
    let minv_at = chol.solve(&a.transpose());
    let s = a * &minv_at;
    let tol = 1e-12 * s.amax().max(1e-300);
    let pinv = s.pseudo_inverse(tol).ok()?;
    Some(minv_at * (pinv * r))
}

/// Project (q, v) onto the constraint manifold in place.
pub fn project(sys: &mut System, q: &mut [f64], v: &mut [f64], positions: bool) -> Result<()> {
    if sys.constraints.is_empty() {
        return Ok(());
    }
    let nv = sys.model.nv;
    if positions {
        for _ in 0..8 {
            sys.constraints
                .evaluate(&sys.model, &mut sys.data, &mut sys.cdata, q, v);
            let rows: Vec<usize> = (0..sys.constraints.nrows)
                .filter(|&k| sys.cdata.holonomic[k])
                .collect();
            let phi = DVector::from_fn(rows.len(), |k, _| sys.cdata.phi[rows[k]]);
            if rows.is_empty() || phi.amax() <= POSITION_TOL {
                break;
            }
            let jh = sys.cdata.j.select_rows(rows.iter());
            let m = crba(&sys.model, &mut sys.data, q).clone();
            let dq =
                weighted_correction(&mass_or_augmented(&m, &jh), &jh, &phi).ok_or_else(|| {
                    Error::InconsistentConstraints {
                        message: "position projection: singular mass matrix".into(),
                    }
                })?;
            let step: Vec<f64> = dq.iter().map(|x| -x).collect();
            let q0 = q.to_vec();
            sys.model.integrate(&q0, &step, 1.0, q);
        }
    }
    sys.constraints
        .evaluate(&sys.model, &mut sys.data, &mut sys.cdata, q, v);
    let j = sys.cdata.j.clone();
    let jv = DVector::from_column_slice(sys.cdata.jv.as_slice());
    if jv.amax() > 0.0 {
        let m = crba(&sys.model, &mut sys.data, q).clone();
        let dv = weighted_correction(&mass_or_augmented(&m, &j), &j, &jv).ok_or_else(|| {
            Error::InconsistentConstraints {
                message: "velocity projection: singular mass matrix".into(),
            }
        })?;
        for i in 0..nv {
            v[i] -= dv[i];
        }
    }
    Ok(())
}

/// M, or M + JᵀJ·max diag(M) when M is only semi-definite (massless links fixed by constraints);
/// the projection onto J v = 0 is the same in either metric restricted to the constraint's range.
fn mass_or_augmented(m: &DMatrix<f64>, j: &DMatrix<f64>) -> DMatrix<f64> {
    if m.clone().cholesky().is_some() {
        return m.clone();
    }
    let rho = m.diagonal().amax().max(1.0);
    m + j.transpose() * j * rho
}
