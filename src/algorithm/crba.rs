//! Composite rigid-body algorithm: the joint-space inertia matrix M(q).

use super::Data;
use crate::model::Model;
use crate::spatial::Motion;
use nalgebra::DMatrix;

/// M(q) into `data.mass_matrix` (both triangles filled).
///
/// Everything in world axes, so no force is carried from frame to frame: with `ᵒS_i` the joint
/// subspace columns and `ᵒY_i` the composite inertia of the subtree of body i,
///   `M[j, i] = ᵒS_jᵀ (ᵒY_i ᵒS_i)` for every ancestor j of i (j = i included),
/// and `ᵒY_λ(i) += ᵒY_i` on the way back to the root.
pub fn crba<'a>(model: &Model, data: &'a mut Data, q: &[f64]) -> &'a DMatrix<f64> {
    super::forward_kinematics_pos(model, data, q);
    crba_after_kinematics(model, data)
}

/// CRBA reusing the placements `o_m_i` of a kinematics pass at the same q.
pub(crate) fn crba_after_kinematics<'a>(model: &Model, data: &'a mut Data) -> &'a DMatrix<f64> {
    for i in 1..model.nbodies() {
        let j = &model.bodies[i].joint;
        data.ycrb[i] = model.bodies[i].inertia.transformed(&data.o_m_i[i]);
        for k in 0..j.kind.nv() {
            data.o_s[i][k] = data.o_m_i[i].act_motion(&j.subspace[k]);
        }
    }
    let m = &mut data.mass_matrix;
    for i in (1..model.nbodies()).rev() {
        let b = &model.bodies[i];
        let ji = &b.joint;
        for k in 0..ji.kind.nv() {
            let f = data.ycrb[i].mul_motion(&data.o_s[i][k]);
            let col = ji.idx_v + k;
            let mut j = i;
            while j != 0 {
                let jj = &model.bodies[j].joint;
                let s: &[Motion; 6] = &data.o_s[j];
                for kk in 0..jj.kind.nv() {
                    let val = s[kk].dot(&f);
                    m[(jj.idx_v + kk, col)] = val;
                    m[(col, jj.idx_v + kk)] = val;
                }
                j = model.bodies[j].parent;
            }
        }
        if b.parent != 0 {
            let yc = data.ycrb[i];
            data.ycrb[b.parent] = data.ycrb[b.parent].add(&yc);
        }
    }
    &data.mass_matrix
}
