//! Analytic derivatives of inverse dynamics τ = RNEA(q, v, q̈) with respect to q and v, and
//! its derivative with respect to q̈, the mass matrix M.
//!
//! Everything is in world axes, where a perturbation δ_j of velocity coordinate j (column ᵒS_j,
//! joint body J with parent P) moves J's subtree rigidly by the motion S = ᵒS_j. For a body k
//! of that subtree, with ᵒv, ᵒa its world twist and acceleration (gravity offset included):
//! - ∂ᵒv_k/∂δ_j = S × (v_k − v_P), ∂ᵒa_k/∂δ_j = S × (a_k − a_P) − (S × v_P) × (v_k − v_P)
//! - ∂ᵒv_k/∂v_j = S, ∂ᵒa_k/∂v_j = v_J × S + S × (v_k − v_P)
//!
//! `body_variation_q`/`_v` give these per body (the constraint rows use them). Inverse dynamics
//! itself is differentiated by composites instead (Carpentier & Mansard, RSS 2018, the
//! algorithm of Pinocchio's `computeRNEADerivatives`): moving J's subtree rigidly is the same as
//! moving everything outside it — P's twist and acceleration, gravity and the world-fixed
//! applied forces — the other way. The τ rows of the subtree therefore see only the change of
//! those surroundings, per column
//! - dV_j = v_P × S, dA_j = a_P × S + v_P × dV_j (from ∂/∂δ_j), dA_j = (v_J + v_P) × S (∂/∂v_j),
//!
//! acting on each subtree's composite inertia Y and its variation Ẏ = v ×* Y − Y v× + (· ×* Y v)
//! summed over the subtree; a row above J sees the subtree's wrench turn with it as well
//! (S ×* F). Cost: one 6-vector product per (ancestor, descendant) coordinate pair and a few 6×6
//! products per body, O(n·d); nothing allocates.

use super::DerivativeData;
use crate::algorithm::{Data, rnea};
use crate::model::Model;
use crate::spatial::{Force, Motion, skew};
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// ∂τ/∂q and ∂τ/∂v of τ = RNEA(q, v, a) into `dd.dtau_dq`, `dd.dtau_dv` (∂/∂q in the tangent
/// space: column j is the derivative along δ_j in q ⊕ δ, docs/architecture.md), and
/// ∂τ/∂a = M(q) into `data.mass_matrix` (both triangles). `data.tau` holds τ afterwards.
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
    passes(model, data, dd);
}

crate::linalg::wide_fn! {
/// The two passes, whose 6×6 products gain from wider vectors.
fn passes(model: &Model, data: &mut Data, dd: &mut DerivativeData) {
    world_pass(model, data, dd);
    backward_pass(model, data, dd);
}
}

/// The matrix of f ↦ v ×* f.
#[inline(always)]
fn force_cross_matrix(v: &Motion) -> Matrix6<f64> {
    let (w, l) = (skew(&v.ang), skew(&v.lin));
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&w);
    m.fixed_view_mut::<3, 3>(3, 0).copy_from(&l);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&w);
    m
}

/// The matrix of x ↦ x ×* h, added to `m`.
#[inline(always)]
fn add_cross_by_force(m: &mut Matrix6<f64>, h: &Force) {
    let (hl, ha) = (skew(&h.lin), skew(&h.ang));
    let mut add = |r: usize, c: usize, x: &Matrix3<f64>| {
        let mut b = m.fixed_view_mut::<3, 3>(r, c);
        b -= x;
    };
    add(0, 3, &hl);
    add(3, 0, &hl);
    add(3, 3, &ha);
}

/// World-axes twists, accelerations, inertias, composite wrenches and subspace columns from the
/// body-frame results of the last RNEA pass; each body's Y, Ẏ and the applied forces' G, and
/// each coordinate's dV, dA of ∂/∂q and dA of ∂/∂v.
#[inline(always)]
fn world_pass(model: &Model, data: &Data, dd: &mut DerivativeData) {
    let nb = model.nbodies();
    dd.o_v[0] = Motion::zero();
    dd.o_a[0] = Motion::new(-model.gravity, Vector3::zeros());
    // Composite applied wrenches, accumulated leaf to root in `df` (scratch here).
    dd.has_applied = false;
    for k in 0..nb {
        dd.df[k] = Force::new(dd.ext_f[k], dd.ext_m[k]);
        dd.has_applied |= dd.ext_f[k] != Vector3::zeros() || dd.ext_m[k] != Vector3::zeros();
    }
    for k in (1..nb).rev() {
        let p = model.bodies[k].parent;
        let w = dd.df[k];
        dd.df[p] += w;
    }
    for k in 1..nb {
        let b = &model.bodies[k];
        let m = &data.o_m_i[k];
        let vk = m.act_motion(&data.v[k]);
        dd.o_v[k] = vk;
        dd.o_a[k] = m.act_motion(&data.a_gf[k]);
        dd.o_inertia[k] = b.inertia.transformed(m);
        dd.o_f[k] = m.act_force(&data.f[k]) - dd.df[k];
        let y = dd.o_inertia[k].matrix();
        // Ẏ = v ×* Y − Y v× + (· ×* Y v); with v× = −(v×*)ᵀ and Y symmetric, the first two
        // terms are A + Aᵀ for A = (v×*) Y.
        let a = force_cross_matrix(&vk) * y;
        dd.dycrb[k] = a + a.transpose();
        add_cross_by_force(&mut dd.dycrb[k], &dd.o_inertia[k].mul_motion(&vk));
        dd.ycrb[k] = y;
        if dd.has_applied {
            dd.gext[k] = applied_force_variation(dd, k);
        }
        let (p, j) = (b.parent, &b.joint);
        let (vp, ap) = (dd.o_v[p], dd.o_a[p]);
        for c in 0..j.kind.nv() {
            let i = j.idx_v + c;
            let s = m.act_motion(&j.subspace[c]);
            dd.o_s[i] = s;
            let dv = vp.cross_motion(&s);
            let col = &mut dd.cols[i];
            col.s = s.to_vector();
            col.dv_dq = dv.to_vector();
            col.da_dq = (ap.cross_motion(&s) + vp.cross_motion(&dv)).to_vector();
            col.da_dv = (vk + vp).cross_motion(&s).to_vector();
        }
    }
}

/// G of body k: how the world-fixed forces applied to it change, seen from the body, when the
/// body moves by S: (ω × f, p × (ω × f)) summed over its points (and ω × m for pure moments),
/// as a matrix on S = (lin, ω): [0, −[F]×; 0, −[n]× − Σ p fᵀ + (Σ p·f) 1].
#[inline(always)]
fn applied_force_variation(dd: &DerivativeData, k: usize) -> Matrix6<f64> {
    let mut g = Matrix6::zeros();
    g.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&-skew(&dd.ext_f[k]));
    g.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(-skew(&dd.ext_m[k]) - dd.ext_pf[k] + Matrix3::identity() * dd.ext_pdotf[k]));
    g
}

/// Leaf to root: each body's composites Y, Ẏ, G (children already added), its coordinates'
/// wrench variations, and the blocks of ∂τ/∂q, ∂τ/∂v and M between its coordinates and those
/// of its subtree.
#[inline(always)]
fn backward_pass(model: &Model, data: &mut Data, dd: &mut DerivativeData) {
    data.size_mass_matrix(model.nv);
    let m = &mut data.mass_matrix;
    dd.dtau_dq.as_mut_slice().fill(0.0);
    dd.dtau_dv.as_mut_slice().fill(0.0);
    m.as_mut_slice().fill(0.0);
    for k in (1..model.nbodies()).rev() {
        let b = &model.bodies[k];
        let (y, dy, g) = (dd.ycrb[k], dd.dycrb[k], dd.gext[k]);
        let (c0, c1, end) = (
            b.joint.idx_v,
            b.joint.idx_v + b.joint.kind.nv(),
            dd.v_end[k],
        );
        let applied = dd.has_applied;
        for c in c0..c1 {
            let col = &mut dd.cols[c];
            col.df_da = y * col.s;
            col.df_dq = dy * col.dv_dq + y * col.da_dq;
            col.df_dv = dy * col.s + y * col.da_dv;
            col.dyt_s = dy.tr_mul(&col.s);
            if applied {
                col.df_dq += g * col.s;
                col.gt_s = g.tr_mul(&col.s);
            }
        }
        for c in c0..c1 {
            let sc = dd.cols[c];
            // Rows below k (their composites already summed), column c.
            for r in c1..end {
                let rc = &dd.cols[r];
                let mut dq = rc.df_da.dot(&sc.da_dq) + rc.dyt_s.dot(&sc.dv_dq);
                if applied {
                    dq += rc.gt_s.dot(&sc.s);
                }
                dd.dtau_dq[(r, c)] = dq;
                dd.dtau_dv[(r, c)] = rc.df_da.dot(&sc.da_dv) + rc.dyt_s.dot(&sc.s);
            }
            // Row c, the columns of k's subtree (k's own included).
            for r in c0..end {
                let rc = &dd.cols[r];
                dd.dtau_dq[(c, r)] = sc.s.dot(&rc.df_dq);
                dd.dtau_dv[(c, r)] = sc.s.dot(&rc.df_dv);
                let mcr = sc.s.dot(&rc.df_da);
                m[(c, r)] = mcr;
                m[(r, c)] = mcr;
            }
        }
        // Rows above k see the subtree's wrench F turn with it: S ×* F.
        let f = dd.o_f[k];
        for c in c0..c1 {
            let turn = dd.o_s[c].cross_force(&f).to_vector();
            dd.cols[c].df_dq += turn;
        }
        let p = b.parent;
        if p != 0 {
            dd.ycrb[p] += y;
            dd.dycrb[p] += dy;
            if applied {
                dd.gext[p] += g;
            }
        }
    }
}

/// The 6-vectors of one velocity coordinate in the backward pass (world axes).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Column {
    /// ᵒS.
    s: Vector6<f64>,
    /// dV = v_P × S and dA = a_P × S + v_P × dV of ∂/∂δ; dA = (v_J + v_P) × S of ∂/∂v.
    dv_dq: Vector6<f64>,
    da_dq: Vector6<f64>,
    da_dv: Vector6<f64>,
    /// Y S, Ẏ dV + Y dA + G S (then + S ×* F), Ẏ S + Y dA, with the composites of its body.
    df_da: Vector6<f64>,
    df_dq: Vector6<f64>,
    df_dv: Vector6<f64>,
    /// Ẏᵀ S and Gᵀ S, what the rows of this coordinate need from the columns above it.
    dyt_s: Vector6<f64>,
    gt_s: Vector6<f64>,
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
