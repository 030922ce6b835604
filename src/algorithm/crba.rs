//! Composite rigid-body algorithm: the joint-space inertia matrix M(q).

use super::Data;
use crate::model::Model;
use crate::spatial::Force;
use nalgebra::DMatrix;

/// M(q) into `data.mass_matrix` (both triangles filled).
///
/// Backward pass: `Yc_i = I_i + Σ children`, `F = Yc_i S_i`, `M[i, i] = S_iᵀ F`, then `F` is carried
/// up the support chain: `M[j, i] = S_jᵀ (j_m_i · F)`.
pub fn crba<'a>(model: &Model, data: &'a mut Data, q: &[f64]) -> &'a DMatrix<f64> {
    super::forward_kinematics_pos(model, data, q);
    for i in 1..model.nbodies() {
        data.ycrb[i] = model.bodies[i].inertia;
    }
    let m = &mut data.mass_matrix;
    for i in (1..model.nbodies()).rev() {
        let b = &model.bodies[i];
        let ji = &b.joint;
        for k in 0..ji.kind.nv() {
            let mut f: Force = data.ycrb[i].mul_motion(&ji.subspace[k]);
            let col = ji.idx_v + k;
            for kk in 0..ji.kind.nv() {
                m[(ji.idx_v + kk, col)] = ji.subspace[kk].dot(&f);
            }
            let mut j = i;
            while model.bodies[j].parent != 0 {
                f = data.li_m_i[j].act_force(&f);
                j = model.bodies[j].parent;
                let jj = &model.bodies[j].joint;
                for kk in 0..jj.kind.nv() {
                    let val = jj.subspace[kk].dot(&f);
                    m[(jj.idx_v + kk, col)] = val;
                    m[(col, jj.idx_v + kk)] = val;
                }
            }
        }
        if b.parent != 0 {
            let yc = data.ycrb[i].transformed(&data.li_m_i[i]);
            data.ycrb[b.parent] = data.ycrb[b.parent].add(&yc);
        }
    }
    &data.mass_matrix
}
