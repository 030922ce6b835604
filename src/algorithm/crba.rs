//! Composite rigid-body algorithm: the joint-space inertia matrix M(q).

use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{Motion, OriginInertia};
use nalgebra::DMatrix;

/// M(q) into `data.mass_matrix` (both triangles filled).
///
/// Everything in world axes, so no force is carried from frame to frame: with `ᵒS_c` the world
/// subspace column of velocity coordinate c and `ᵒY_i` the composite inertia of the subtree of
/// body i (c's body),
///   `M[c, r] = ᵒS_rᵀ F_c`, `F_c = ᵒY_i ᵒS_c`, for every coordinate c that r moves,
/// and `ᵒY_λ(i) += ᵒY_i` on the way back to the root. The composite inertias are kept about the
/// world origin ([`OriginInertia`]), where summing them is plain addition. Coordinates are
/// numbered depth-first, so the coordinates r moves are one range (`Model::v_subtree_end`),
/// whose forces are computed when r's body is reached: each row is a run of dot products over
/// contiguous memory, no walk up the tree. A free-flyer base's six rows of a column are its
/// force F_c expressed in the base frame (its S is the identity there): one transform instead
/// of six dot products, on every column of a floating robot; and the base's own 6 × 6 block is
/// the whole robot's composite inertia expressed in the base frame
/// ([`OriginInertia::expressed_in`]), with no subspace columns or forces of its own.
pub fn crba<'a>(model: &Model, data: &'a mut Data, q: &[f64]) -> &'a DMatrix<f64> {
    // (One loop for the kinematics and the forward sweep measured 15–25 % slower.)
    super::forward_kinematics_pos(model, data, q);
    crba_after_kinematics(model, data)
}

/// CRBA reusing the placements `o_m_i` of a kinematics pass at the same q.
pub(crate) fn crba_after_kinematics<'a>(model: &Model, data: &'a mut Data) -> &'a DMatrix<f64> {
    let base_nv = free_flyer_base_nv(model);
    for i in 1..model.nbodies() {
        forward(model, data, i, base_nv);
    }
    backward(model, data, base_nv)
}

/// Velocity coordinates 0..6 of a free-flyer base (body 1), or none.
#[inline]
fn free_flyer_base_nv(model: &Model) -> usize {
    match model.bodies.get(1).map(|b| &b.joint) {
        Some(j) if matches!(j.kind, JointKind::FreeFlyer) && j.idx_v == 0 => 6,
        _ => 0,
    }
}

/// Body i's inertia and subspace columns in world axes.
#[inline(always)]
fn forward(model: &Model, data: &mut Data, i: usize, base_nv: usize) {
    let b = &model.bodies[i];
    let j = &b.joint;
    let o_m_i = &data.o_m_i[i];
    data.ycrb[i] = OriginInertia::transformed(&b.inertia, o_m_i);
    if j.idx_v < base_nv {
        // The free-flyer base: its block comes from the composite inertia (`backward`).
        return;
    }
    if let JointKind::Revolute { axis, aligned, .. } = &j.kind {
        // A pure rotation: ᵒS = (t × R a, R a), without `act_motion`'s product of R with
        // the zero linear part; R a is a column of R when a is a frame axis.
        let ang = match aligned {
            Some((k, sign)) => o_m_i.rotation.column(*k) * *sign,
            None => o_m_i.rotation * axis,
        };
        data.o_s[j.idx_v] = Motion::new(o_m_i.translation.cross(&ang), ang);
    } else {
        for k in 0..j.kind.nv() {
            data.o_s[j.idx_v + k] = o_m_i.act_motion(&j.subspace[k]);
        }
    }
}

/// The composite inertias from the leaves to the root, and M.
fn backward<'a>(model: &Model, data: &'a mut Data, base_nv: usize) -> &'a DMatrix<f64> {
    let nv = model.nv;
    let m = data.mass_matrix.as_mut_slice();
    let (o_s, f_crb) = (&data.o_s, &mut data.f_crb);
    for i in (1..model.nbodies()).rev() {
        let b = &model.bodies[i];
        let ji = &b.joint;
        let y = data.ycrb[i];
        let cols = ji.idx_v.max(base_nv)..ji.idx_v + ji.kind.nv();
        for c in cols.clone() {
            f_crb[c] = y.mul_motion(&o_s[c]);
        }
        // Row r against every column r moves (its subtree, one contiguous range of forces
        // already computed): the lower triangle's column r, contiguous in memory.
        for r in cols.clone() {
            let s_r = o_s[r];
            let end = model.v_subtree_end[r];
            for (c, f) in (r..end).zip(&f_crb[r..end]) {
                let x = s_r.dot(f);
                m[r * nv + c] = x;
                m[c * nv + r] = x;
            }
        }
        if b.parent != 0 {
            data.ycrb[b.parent] += y;
        }
    }
    if base_nv > 0 {
        let o_m_b = &data.o_m_i[1];
        // The base block: m 1, −[h]× / [h]×, I of the whole robot about the base origin.
        let y = data.ycrb[1].expressed_in(o_m_b);
        let (h, [xx, yy, zz, xy, xz, yz]) = (y.h, y.i_o);
        #[rustfmt::skip]
        let block = [
            [y.mass, 0.0, 0.0, 0.0, h.z, -h.y],
            [0.0, y.mass, 0.0, -h.z, 0.0, h.x],
            [0.0, 0.0, y.mass, h.y, -h.x, 0.0],
            [0.0, -h.z, h.y, xx, xy, xz],
            [h.z, 0.0, -h.x, xy, yy, yz],
            [-h.y, h.x, 0.0, xz, yz, zz],
        ];
        for (c, col) in block.iter().enumerate() {
            m[c * nv..c * nv + 6].copy_from_slice(col);
        }
        // Column c's base rows: its force in the base frame (the lower triangle's rows 0..6).
        for (c, f) in f_crb.iter().enumerate().skip(6) {
            let fb = o_m_b.act_inv_force(f);
            let rows = [fb.lin.x, fb.lin.y, fb.lin.z, fb.ang.x, fb.ang.y, fb.ang.z];
            for (r, x) in rows.into_iter().enumerate() {
                m[r * nv + c] = x;
                m[c * nv + r] = x;
            }
        }
    }
    &data.mass_matrix
}
