//! Recursive Newton–Euler: inverse dynamics `τ = M(q) q̈ + C(q, v) v + g(q)`.

use super::Data;
use crate::model::Model;
use crate::spatial::Motion;
use nalgebra::{DVector, Vector3};

/// τ = ID(q, v, q̈) into `data.tau`. Gravity enters as a fictitious base acceleration `−g`.
pub fn rnea<'a>(
    model: &Model,
    data: &'a mut Data,
    q: &[f64],
    v: &[f64],
    a: &[f64],
) -> &'a DVector<f64> {
    rnea_impl(model, data, q, v, Some(a))
}

/// Bias forces `h(q, v) = C(q, v) v + g(q)` (RNEA with q̈ = 0) into `data.tau`.
pub fn nonlinear_effects<'a>(
    model: &Model,
    data: &'a mut Data,
    q: &[f64],
    v: &[f64],
) -> &'a DVector<f64> {
    rnea_impl(model, data, q, v, None)
}

fn rnea_impl<'a>(
    model: &Model,
    data: &'a mut Data,
    q: &[f64],
    v: &[f64],
    a: Option<&[f64]>,
) -> &'a DVector<f64> {
    data.a_gf[0] = Motion::new(-model.gravity, Vector3::zeros());
    for i in 1..model.nbodies() {
        let b = &model.bodies[i];
        let j = &b.joint;
        super::kinematics::place(model, data, i, q);
        let li = data.li_m_i[i];
        let mut vj = Motion::zero();
        let mut aj = Motion::zero();
        for k in 0..j.kind.nv() {
            vj += j.subspace[k] * v[j.idx_v + k];
            if let Some(a) = a {
                aj += j.subspace[k] * a[j.idx_v + k];
            }
        }
        let vi = li.act_inv_motion(&data.v[b.parent]) + vj;
        let ai = li.act_inv_motion(&data.a_gf[b.parent]) + aj + vi.cross_motion(&vj);
        data.v[i] = vi;
        data.a_gf[i] = ai;
        let iv = b.inertia.mul_motion(&vi);
        data.f[i] = b.inertia.mul_motion(&ai) + vi.cross_force(&iv);
    }
    backward_pass(model, data);
    &data.tau
}

/// Bias forces h into `data.tau` reusing a `forward_kinematics` pass at (q, v, q̈ = 0): the
/// accelerations with gravity are `a_i + (R_iᵀ(−g), 0)`, so no second forward pass is needed.
pub(crate) fn bias_forces_after_kinematics(model: &Model, data: &mut Data) {
    for i in 1..model.nbodies() {
        let b = &model.bodies[i];
        let g_local = data.o_m_i[i].rotation.tr_mul(&(-model.gravity));
        let ai = data.a[i] + Motion::new(g_local, Vector3::zeros());
        let vi = data.v[i];
        let iv = b.inertia.mul_motion(&vi);
        data.f[i] = b.inertia.mul_motion(&ai) + vi.cross_force(&iv);
    }
    backward_pass(model, data);
}

/// τ_i = S_iᵀ f_i, accumulating each body's wrench into its parent.
fn backward_pass(model: &Model, data: &mut Data) {
    for i in (1..model.nbodies()).rev() {
        let b = &model.bodies[i];
        let j = &b.joint;
        for k in 0..j.kind.nv() {
            data.tau[j.idx_v + k] = j.subspace[k].dot(&data.f[i]);
        }
        if b.parent > 0 {
            let fp = data.li_m_i[i].act_force(&data.f[i]);
            data.f[b.parent] += fp;
        }
    }
}
