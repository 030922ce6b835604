//! Composite rigid-body algorithm: the joint-space inertia matrix M(q).

use super::Data;
use crate::linalg::NO_PARENT;
use crate::model::{JointKind, Model};
use crate::spatial::{Motion, OriginInertia};
use nalgebra::DMatrix;

/// M(q) into `data.mass_matrix` (both triangles filled).
///
/// Everything in world axes, so no force is carried from frame to frame: with `ᵒS_c` the world
/// subspace column of velocity coordinate c and `ᵒY_i` the composite inertia of the subtree of
/// body i (c's body),
///   `M[r, c] = ᵒS_rᵀ (ᵒY_i ᵒS_c)` for every coordinate r on the path from c to the root,
/// and `ᵒY_λ(i) += ᵒY_i` on the way back to the root. The composite inertias are kept about the
/// world origin ([`OriginInertia`]), where summing them is plain addition; the path is walked
/// through `Model::v_parent`, one flat array. A free-flyer base's six rows of a column are its
/// force ᵒY_i ᵒS_c expressed in the base frame (its S is the identity there): one transform
/// instead of six dot products, on every column of a floating robot.
pub fn crba<'a>(model: &Model, data: &'a mut Data, q: &[f64]) -> &'a DMatrix<f64> {
    super::forward_kinematics_pos(model, data, q);
    crba_after_kinematics(model, data)
}

/// CRBA reusing the placements `o_m_i` of a kinematics pass at the same q.
pub(crate) fn crba_after_kinematics<'a>(model: &Model, data: &'a mut Data) -> &'a DMatrix<f64> {
    for i in 1..model.nbodies() {
        let b = &model.bodies[i];
        let j = &b.joint;
        let o_m_i = &data.o_m_i[i];
        data.ycrb[i] = OriginInertia::transformed(&b.inertia, o_m_i);
        if let JointKind::Revolute { axis, .. } = &j.kind {
            // A pure rotation: ᵒS = (t × R a, R a), without `act_motion`'s product of R with
            // the zero linear part.
            let ang = o_m_i.rotation * axis;
            data.o_s[j.idx_v] = Motion::new(o_m_i.translation.cross(&ang), ang);
        } else {
            for k in 0..j.kind.nv() {
                data.o_s[j.idx_v + k] = o_m_i.act_motion(&j.subspace[k]);
            }
        }
    }
    let nv = model.nv;
    // Velocity coordinates 0..6 of a free-flyer base (body 1), or none.
    let base_nv = match model.bodies.get(1).map(|b| &b.joint) {
        Some(j) if matches!(j.kind, JointKind::FreeFlyer) && j.idx_v == 0 => 6,
        _ => 0,
    };
    let m = data.mass_matrix.as_mut_slice();
    let (o_s, parent) = (&data.o_s, &model.v_parent);
    for i in (1..model.nbodies()).rev() {
        let b = &model.bodies[i];
        let ji = &b.joint;
        let y = data.ycrb[i];
        for c in ji.idx_v..ji.idx_v + ji.kind.nv() {
            let f = y.mul_motion(&o_s[c]);
            // Column-major: (r, c) at c·nv + r (upper triangle, r ≤ c) and (c, r) at r·nv + c.
            let mut r = c;
            while r != NO_PARENT && r >= base_nv {
                let x = o_s[r].dot(&f);
                m[c * nv + r] = x;
                m[r * nv + c] = x;
                r = parent[r];
            }
            if base_nv > 0 {
                let fb = data.o_m_i[1].act_inv_force(&f);
                let rows = [fb.lin.x, fb.lin.y, fb.lin.z, fb.ang.x, fb.ang.y, fb.ang.z];
                for (r, x) in rows.into_iter().enumerate() {
                    m[c * nv + r] = x;
                    m[r * nv + c] = x;
                }
            }
        }
        if b.parent != 0 {
            data.ycrb[b.parent] += y;
        }
    }
    &data.mass_matrix
}
