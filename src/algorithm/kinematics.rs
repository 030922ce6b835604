//! Forward kinematics: poses, twists and accelerations of bodies, frames and points.

use super::Data;
use crate::model::Model;
use crate::spatial::{Motion, SE3};
use nalgebra::Vector3;

/// Body i's placements at q: `li_m_i = placement · X_J(q)`, `o_m_i = o_m_parent · li_m_i`.
#[inline(always)]
pub(crate) fn place(model: &Model, data: &mut Data, i: usize, q: &[f64]) {
    let b = &model.bodies[i];
    let j = &b.joint;
    if let Some(o) = b.placed_in_world(q, &data.o_m_i[b.parent], &mut data.li_m_i[i]) {
        data.o_m_i[i] = o;
    } else {
        let qi = &q[j.idx_q..j.idx_q + j.kind.nq()];
        data.li_m_i[i] = j.kind.placed(&b.placement, qi);
        data.o_m_i[i] = data.o_m_i[b.parent].compose(&data.li_m_i[i]);
    }
}

/// Joint placements: `li_m_i = placement · X_J(q)`, `o_m_i = o_m_parent · li_m_i`.
pub fn forward_kinematics_pos(model: &Model, data: &mut Data, q: &[f64]) {
    for i in 1..model.nbodies() {
        place(model, data, i, q);
    }
}

/// Placements, body twists `v_i = li_m_iᵀ v_λ + S q̇_i` and accelerations
/// `a_i = li_m_iᵀ a_λ + S q̈_i + v_i × S q̇_i` (body frames, no gravity).
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &[f64], v: &[f64], a: &[f64]) {
    for i in 1..model.nbodies() {
        let b = &model.bodies[i];
        let j = &b.joint;
        place(model, data, i, q);
        let (vj, aj) = joint_motion(j, v, a);
        let vi = data.li_m_i[i].act_inv_motion(&data.v[b.parent]) + vj;
        data.a[i] = data.li_m_i[i].act_inv_motion(&data.a[b.parent]) + aj + vi.cross_motion(&vj);
        data.v[i] = vi;
    }
}

/// [`forward_kinematics`] at q̈ = 0: placements, twists and the bias accelerations
/// `a_i = li_m_iᵀ a_λ + v_i × S q̇_i` that the constraints' γ and the bias forces read, without
/// forming and adding the zero `S q̈_i` terms (the same numbers).
pub fn forward_kinematics_bias(model: &Model, data: &mut Data, q: &[f64], v: &[f64]) {
    for i in 1..model.nbodies() {
        let (vj, vi) = place_with_twist(model, data, i, q, v);
        let parent = model.bodies[i].parent;
        data.a[i] = data.li_m_i[i].act_inv_motion(&data.a[parent]) + vi.cross_motion(&vj);
        data.v[i] = vi;
    }
}

/// [`forward_kinematics_bias`] from the placements `li_m_i` already in `data` at the same q (a
/// CRBA's): twists and bias accelerations only, no joint transforms formed again.
pub(crate) fn forward_kinematics_bias_after_placements(model: &Model, data: &mut Data, v: &[f64]) {
    for i in 1..model.nbodies() {
        let b = &model.bodies[i];
        let j = &b.joint;
        let mut vj = Motion::zero();
        for k in 0..j.kind.nv() {
            vj += j.subspace[k] * v[j.idx_v + k];
        }
        let li = &data.li_m_i[i];
        let vi = li.act_inv_motion(&data.v[b.parent]) + vj;
        data.a[i] = li.act_inv_motion(&data.a[b.parent]) + vi.cross_motion(&vj);
        data.v[i] = vi;
    }
}

/// Placements and body twists without accelerations: what the residuals a sample reports and
/// the kinetic energy read (`ConstraintSet::residuals`).
pub fn forward_kinematics_vel(model: &Model, data: &mut Data, q: &[f64], v: &[f64]) {
    for i in 1..model.nbodies() {
        data.v[i] = place_with_twist(model, data, i, q, v).1;
    }
}

/// Body i placed at q, and (S q̇_i, its twist `v_i = li_m_iᵀ v_λ + S q̇_i`) from its parent's.
#[inline(always)]
fn place_with_twist(
    model: &Model,
    data: &mut Data,
    i: usize,
    q: &[f64],
    v: &[f64],
) -> (Motion, Motion) {
    let b = &model.bodies[i];
    let j = &b.joint;
    place(model, data, i, q);
    let mut vj = Motion::zero();
    for k in 0..j.kind.nv() {
        vj += j.subspace[k] * v[j.idx_v + k];
    }
    (vj, data.li_m_i[i].act_inv_motion(&data.v[b.parent]) + vj)
}

/// `(S q̇_i, S q̈_i)` of one joint.
#[inline]
pub(crate) fn joint_motion(j: &crate::model::Joint, v: &[f64], a: &[f64]) -> (Motion, Motion) {
    let mut vj = Motion::zero();
    let mut aj = Motion::zero();
    for k in 0..j.kind.nv() {
        vj += j.subspace[k] * v[j.idx_v + k];
        aj += j.subspace[k] * a[j.idx_v + k];
    }
    (vj, aj)
}

/// `world_m_frame` (after a kinematics pass).
pub fn frame_placement(model: &Model, data: &Data, frame: usize) -> SE3 {
    let f = &model.frames[frame];
    data.o_m_i[f.body].compose(&f.placement)
}

/// Twist of a frame expressed in that frame (after `forward_kinematics`).
pub fn frame_velocity(model: &Model, data: &Data, frame: usize) -> Motion {
    let f = &model.frames[frame];
    f.placement.act_inv_motion(&data.v[f.body])
}

/// World position of a point `p` given in `frame` [m].
pub fn point_position(model: &Model, data: &Data, frame: usize, p: &Vector3<f64>) -> Vector3<f64> {
    let f = &model.frames[frame];
    data.o_m_i[f.body].act_point(&f.placement.act_point(p))
}

/// World-axes velocity of the material point `p` of `frame` [m/s].
pub fn point_velocity(model: &Model, data: &Data, frame: usize, p: &Vector3<f64>) -> Vector3<f64> {
    let f = &model.frames[frame];
    let pb = f.placement.act_point(p);
    let v = &data.v[f.body];
    data.o_m_i[f.body].rotation * (v.lin + v.ang.cross(&pb))
}

/// World-axes classical acceleration of the material point `p` of `frame` [m/s²]:
/// `R (a_lin + α × p + ω × (v_lin + ω × p))`. With the accelerations of `forward_kinematics`
/// at q̈ = 0 this is the `J̇ v` term of a point constraint.
pub fn point_classical_acceleration(
    model: &Model,
    data: &Data,
    frame: usize,
    p: &Vector3<f64>,
) -> Vector3<f64> {
    let f = &model.frames[frame];
    let pb = f.placement.act_point(p);
    let v = &data.v[f.body];
    let a = &data.a[f.body];
    let vp = v.lin + v.ang.cross(&pb);
    data.o_m_i[f.body].rotation * (a.lin + a.ang.cross(&pb) + v.ang.cross(&vp))
}
