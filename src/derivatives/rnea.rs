//! Analytic derivatives of inverse dynamics τ = RNEA(q, v, q̈) with respect to q and v.
//!
//! Everything is expressed in world axes, where a perturbation δ_j of velocity coordinate j
//! (column ᵒS_j, joint body J with parent P) moves J's whole subtree rigidly by the motion ᵒS_j.
//! For a body k of that subtree, with ᵒv, ᵒa its world twist and acceleration (gravity offset
//! included) and ᵒI its world inertia:
//! - ∂ᵒv_k/∂δ_j = S × (v_k − v_P)
//! - ∂ᵒa_k/∂δ_j = S × (a_k − a_P) − (S × v_P) × (v_k − v_P)
//! - ∂ᵒI_k/∂δ_j · x = S ×* (I x) − I (S × x)
//! - ∂ᵒS_i/∂δ_j = S × S_i for the coordinates i of the subtree (J's own included)
//!
//! and for a velocity coordinate j: ∂ᵒv_k/∂v_j = S, ∂ᵒa_k/∂v_j = v_J × S + S × (v_k − v_P).
//! The body wrench f = I a + v ×* I v varies accordingly; composite wrenches F of the subtree
//! and of J's ancestors give ∂τ_i = ∂S_i · F_i + S_i · ∂F_i. Bodies outside J's subtree and
//! coordinates neither in it nor above it do not move. Cost per column: the subtree plus the
//! depth, O(n·d) in all; nothing allocates.

use super::DerivativeData;
use crate::algorithm::{Data, rnea};
use crate::model::Model;
use crate::spatial::{Force, Motion};
use nalgebra::Vector3;

/// ∂τ/∂q and ∂τ/∂v of τ = RNEA(q, v, a) into `dd.dtau_dq`, `dd.dtau_dv` (∂/∂q in the tangent
/// space: column j is the derivative along δ_j in q ⊕ δ, docs/architecture.md). `data.tau`
/// holds τ afterwards. ∂τ/∂a is the mass matrix ([`crate::algorithm::crba`]).
pub fn rnea_derivatives(
    model: &Model,
    data: &mut Data,
    dd: &mut DerivativeData,
    q: &[f64],
    v: &[f64],
    a: &[f64],
) {
    dd.clear_point_forces();
    rnea_derivatives_with_point_forces(model, data, dd, q, v, a);
}

/// As [`rnea_derivatives`], for τ − Σ (generalized force of the point forces registered with
/// `DerivativeData::add_point_force`, fixed in world axes, applied at points moving with their
/// bodies). The constrained derivatives use it for ∂(RNEA − Jᵀλ)/∂q at fixed λ.
pub(crate) fn rnea_derivatives_with_point_forces(
    model: &Model,
    data: &mut Data,
    dd: &mut DerivativeData,
    q: &[f64],
    v: &[f64],
    a: &[f64],
) {
    rnea(model, data, q, v, a);
    world_pass(model, data, dd);
    for j in 0..model.nv {
        column_dq(model, dd, j);
        column_dv(model, dd, j);
    }
}

/// World-axes twists, accelerations, inertias, composite wrenches and subspace columns from the
/// body-frame results of the last RNEA pass.
fn world_pass(model: &Model, data: &Data, dd: &mut DerivativeData) {
    let nb = model.nbodies();
    dd.o_v[0] = Motion::zero();
    dd.o_a[0] = Motion::new(-model.gravity, Vector3::zeros());
    // Composite applied wrenches, accumulated leaf to root in `df` (scratch here).
    for k in 0..nb {
        dd.df[k] = Force::new(dd.ext_f[k], dd.ext_m[k]);
    }
    for k in (1..nb).rev() {
        let p = model.bodies[k].parent;
        let w = dd.df[k];
        dd.df[p] += w;
    }
    for k in 1..nb {
        let b = &model.bodies[k];
        let m = &data.o_m_i[k];
        dd.o_v[k] = m.act_motion(&data.v[k]);
        dd.o_a[k] = m.act_motion(&data.a_gf[k]);
        dd.o_inertia[k] = b.inertia.transformed(m);
        dd.o_f[k] = m.act_force(&data.f[k]) - dd.df[k];
        let j = &b.joint;
        for c in 0..j.kind.nv() {
            dd.o_s[j.idx_v + c] = m.act_motion(&j.subspace[c]);
        }
    }
}

/// Column j of ∂τ/∂q.
fn column_dq(model: &Model, dd: &mut DerivativeData, j: usize) {
    let body_j = dd.dof_body[j];
    let end = dd.subtree_end[body_j];
    let s = dd.o_s[j];
    for k in body_j..end {
        let (vk, ak, inertia) = (dd.o_v[k], dd.o_a[k], dd.o_inertia[k]);
        let (dv, da) = body_variation_q(model, dd, k, j).expect("k in j's subtree");
        let ia = inertia.mul_motion(&ak);
        let iv = inertia.mul_motion(&vk);
        let di_a = s.cross_force(&ia) - inertia.mul_motion(&s.cross_motion(&ak));
        let di_v = s.cross_force(&iv) - inertia.mul_motion(&s.cross_motion(&vk));
        let mut df = di_a
            + inertia.mul_motion(&da)
            + dv.cross_force(&iv)
            + vk.cross_force(&(di_v + inertia.mul_motion(&dv)));
        // The applied point forces: f fixed in world axes, its point moving by S's velocity
        // field, so only the moment changes: (s_lin + s_ang × p) × f summed over the points.
        let dm = s.lin.cross(&dd.ext_f[k]) + dd.ext_pf[k] * s.ang - s.ang * dd.ext_pdotf[k];
        df.ang -= dm;
        dd.df[k] = df;
    }
    accumulate_and_project(model, dd, j, body_j, end, Some(s));
}

/// Column j of ∂τ/∂v.
fn column_dv(model: &Model, dd: &mut DerivativeData, j: usize) {
    let body_j = dd.dof_body[j];
    let end = dd.subtree_end[body_j];
    let s = dd.o_s[j];
    for k in body_j..end {
        let (vk, inertia) = (dd.o_v[k], dd.o_inertia[k]);
        let (_, da) = body_variation_v(model, dd, k, j).expect("k in j's subtree");
        let iv = inertia.mul_motion(&vk);
        dd.df[k] =
            inertia.mul_motion(&da) + s.cross_force(&iv) + vk.cross_force(&inertia.mul_motion(&s));
    }
    accumulate_and_project(model, dd, j, body_j, end, None);
}

/// Sums the subtree's wrench variations `dd.df` into composites and writes column j of ∂τ/∂q
/// (`moving = Some(S_j)`: the subtree's columns rotate too) or of ∂τ/∂v (`None`).
fn accumulate_and_project(
    model: &Model,
    dd: &mut DerivativeData,
    j: usize,
    body_j: usize,
    end: usize,
    moving: Option<Motion>,
) {
    for k in (body_j + 1..end).rev() {
        let p = model.bodies[k].parent;
        let w = dd.df[k];
        dd.df[p] += w;
    }
    let out = match moving {
        Some(_) => &mut dd.dtau_dq,
        None => &mut dd.dtau_dv,
    };
    out.column_mut(j).fill(0.0);
    for k in body_j..end {
        let jk = &model.bodies[k].joint;
        for c in 0..jk.kind.nv() {
            let i = jk.idx_v + c;
            let mut d = dd.o_s[i].dot(&dd.df[k]);
            if let Some(s) = moving {
                d += s.cross_motion(&dd.o_s[i]).dot(&dd.o_f[k]);
            }
            out[(i, j)] = d;
        }
    }
    let dfj = dd.df[body_j];
    let mut b = model.bodies[body_j].parent;
    while b > 0 {
        let jb = &model.bodies[b].joint;
        for c in 0..jb.kind.nv() {
            let i = jb.idx_v + c;
            out[(i, j)] = dd.o_s[i].dot(&dfj);
        }
        b = model.bodies[b].parent;
    }
}

/// Variation (∂ᵒv_k, ∂ᵒa_k) of body k's world twist and acceleration along q-column j, or None
/// when k is not in j's subtree (it does not move).
pub(crate) fn body_variation_q(
    model: &Model,
    dd: &DerivativeData,
    k: usize,
    j: usize,
) -> Option<(Motion, Motion)> {
    let body_j = dd.dof_body[j];
    if k < body_j || k >= dd.subtree_end[body_j] {
        return None;
    }
    let p = model.bodies[body_j].parent;
    let s = dd.o_s[j];
    let (vp, ap) = (dd.o_v[p], dd.o_a[p]);
    let rel_v = dd.o_v[k] - vp;
    let dv = s.cross_motion(&rel_v);
    let da = s.cross_motion(&(dd.o_a[k] - ap)) - s.cross_motion(&vp).cross_motion(&rel_v);
    Some((dv, da))
}

/// Variation (∂ᵒv_k, ∂ᵒa_k) along velocity coordinate j, or None outside j's subtree.
pub(crate) fn body_variation_v(
    model: &Model,
    dd: &DerivativeData,
    k: usize,
    j: usize,
) -> Option<(Motion, Motion)> {
    let body_j = dd.dof_body[j];
    if k < body_j || k >= dd.subtree_end[body_j] {
        return None;
    }
    let p = model.bodies[body_j].parent;
    let s = dd.o_s[j];
    let da = dd.o_v[body_j].cross_motion(&s) + s.cross_motion(&(dd.o_v[k] - dd.o_v[p]));
    Some((s, da))
}

/// −(S_i · W) for the coordinates above `body`, W = (δf, p × δf + δm): a variation of an applied
/// force's direction (or point) that RNEA's material-point term did not include.
pub(crate) fn subtract_force_variation(
    model: &Model,
    dd: &mut DerivativeData,
    body: usize,
    j: usize,
    w: Force,
) {
    let mut b = body;
    while b > 0 {
        let jb = &model.bodies[b].joint;
        for c in 0..jb.kind.nv() {
            let i = jb.idx_v + c;
            dd.dtau_dq[(i, j)] -= dd.o_s[i].dot(&w);
        }
        b = model.bodies[b].parent;
    }
}
