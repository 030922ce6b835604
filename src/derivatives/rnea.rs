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
//! (S ×* F). Y is kept about the world origin in its additive form (`OriginInertia`), and Ẏ,
//! whose left three columns vanish, as its right half (`AngularColumns`). Cost: one 6-vector
//! product per (ancestor, descendant) coordinate pair and a few 3×3 products per body, O(n·d);
//! nothing allocates.

use super::DerivativeData;
use crate::algorithm::{Data, rnea};
use crate::model::{JointKind, Model};
use crate::spatial::{Force, Motion, OriginInertia, skew};
use nalgebra::{DMatrix, Matrix3, Vector3};

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
    rnea(model, data, q, v, a);
    passes(model, data, dd, Accelerations::Rnea);
}

/// As [`rnea_derivatives`] at a = q̈, for τ − Σ (generalized force of the point forces
/// registered with `DerivativeData::add_point_force`, fixed in world axes, applied at points
/// moving with their bodies), from the bias pass at q̈ = 0 already in `data` (placements,
/// twists, `data.a` and the composite bias wrenches `data.f` of
/// `bias_forces_after_kinematics`): q̈'s share of the accelerations and wrenches is added in
/// world axes, where it needs no transform (ᵒa_k += ᵒa_λ's share + Σ ᵒS q̈), instead of a
/// second RNEA. M is not written (the caller's CRBA has it). The forward dynamics' derivatives
/// use it, with the constraint forces λ as the point forces for ∂(RNEA − Jᵀλ)/∂q.
pub(crate) fn rnea_derivatives_after_bias(
    model: &Model,
    data: &mut Data,
    dd: &mut DerivativeData,
    qdd: &[f64],
) {
    passes(model, data, dd, Accelerations::BiasPlus(qdd));
}

/// Where the passes find the bodies' accelerations and composite wrenches.
#[derive(Clone, Copy)]
enum Accelerations<'a> {
    /// `data.a_gf` and `data.f` of an RNEA at a; M is written.
    Rnea,
    /// `data.a` and `data.f` of the bias pass, plus the share of this q̈; M is not written.
    BiasPlus(&'a [f64]),
}

crate::linalg::wide_fn! {
/// The two passes, whose 6×6 products gain from wider vectors.
fn passes(model: &Model, data: &mut Data, dd: &mut DerivativeData, acc: Accelerations<'_>) {
    world_pass(model, data, dd, acc);
    backward_pass(model, data, dd, matches!(acc, Accelerations::Rnea));
}
}

/// A 6 × 6 matrix on (lin, ang) whose left three columns are zero, `[[0, [t]×], [0, B]]`: the
/// form of Ẏ and of G (below), kept as t and B (12 numbers added per body instead of 36, and
/// half the products).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct AngularColumns {
    t: Vector3<f64>,
    b: Matrix3<f64>,
}

impl AngularColumns {
    /// The matrix times the motion x: (t × x_ang, B x_ang).
    #[inline(always)]
    fn mul(&self, x: &Motion) -> Force {
        Force::new(self.t.cross(&x.ang), self.b * x.ang)
    }

    /// The angular part of the matrix's transpose times s (its linear part is zero):
    /// [t]×ᵀ s_lin + Bᵀ s_ang = s_lin × t + Bᵀ s_ang.
    #[inline(always)]
    fn tr_mul(&self, s: &Motion) -> Vector3<f64> {
        s.lin.cross(&self.t) + self.b.tr_mul(&s.ang)
    }
}

impl std::ops::AddAssign for AngularColumns {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        self.t += o.t;
        self.b += o.b;
    }
}

/// Ẏ = v ×* Y − Y v× + (· ×* Y v) of one body's world inertia Y = [[m 1, −[h]×], [[h]×, I]]
/// (about the world origin) moving with the world twist v = (v, ω). With V, H, W the cross
/// matrices of v, h, ω and (p, L) = Y v, the first two terms are A + Aᵀ for A = (v ×*) Y =
/// [[m W, −W H], [m V + W H, −V H + W I]]; with [a]×[b]× − [b]×[a]× = [a × b]× their left
/// column cancels that of the third term, [[0, −[p]×], [−[p]×, −[L]×]], and
///   Ẏ = [[0, −2 [p]×], [0, −(V H + H V) + W I + (W I)ᵀ − [L]×]],
/// with V H + H V = h vᵀ + v hᵀ − 2 (v·h) 1.
#[inline(always)]
fn inertia_variation(y: &OriginInertia, v: &Motion) -> AngularColumns {
    let yv = y.mul_motion(v);
    let (h, w, l) = (y.h, v.ang, v.lin);
    let [xx, yy, zz, xy, xz, yz] = y.i_o;
    let i = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    // W I, column by column: ω × (column of I).
    let wi = Matrix3::from_columns(&[
        w.cross(&i.column(0).into_owned()),
        w.cross(&i.column(1).into_owned()),
        w.cross(&i.column(2).into_owned()),
    ]);
    let hv = h * l.transpose();
    let mut b = wi + wi.transpose() - hv - hv.transpose();
    let d = 2.0 * h.dot(&l);
    let n = yv.ang;
    b[(0, 0)] += d;
    b[(1, 1)] += d;
    b[(2, 2)] += d;
    // − [L]×
    b[(0, 1)] += n.z;
    b[(0, 2)] -= n.y;
    b[(1, 0)] -= n.z;
    b[(1, 2)] += n.x;
    b[(2, 0)] += n.y;
    b[(2, 1)] -= n.x;
    AngularColumns {
        t: yv.lin * -2.0,
        b,
    }
}

/// Body i's world subspace column c: for a revolute joint a pure rotation about its world axis
/// through the body origin, (t × R a, R a) (R a a column of R when a is a frame axis), as CRBA
/// forms it.
#[inline(always)]
fn world_subspace(kind: &JointKind, o_m_i: &crate::spatial::SE3, s: &Motion) -> Motion {
    if let JointKind::Revolute { axis, aligned, .. } = kind {
        let ang = match aligned {
            Some((k, sign)) => o_m_i.rotation.column(*k) * *sign,
            None => o_m_i.rotation * axis,
        };
        Motion::new(o_m_i.translation.cross(&ang), ang)
    } else {
        o_m_i.act_motion(s)
    }
}

/// World-axes twists, accelerations, composite wrenches and subspace columns from the
/// body-frame results of the last RNEA or bias pass; each body's Y, Ẏ and the applied forces'
/// G, and each coordinate's dV, dA of ∂/∂q and dA of ∂/∂v.
#[inline(always)]
fn world_pass(model: &Model, data: &Data, dd: &mut DerivativeData, acc: Accelerations<'_>) {
    let nb = model.nbodies();
    let gravity_offset = Motion::new(-model.gravity, Vector3::zeros());
    dd.o_v[0] = Motion::zero();
    dd.o_a[0] = gravity_offset;
    dd.o_aq[0] = Motion::zero();
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
        let (p, j) = (b.parent, &b.joint);
        for c in 0..j.kind.nv() {
            dd.o_s[j.idx_v + c] = world_subspace(&j.kind, m, &j.subspace[c]);
        }
        dd.o_f[k] = m.act_force(&data.f[k]) - dd.df[k];
        match acc {
            Accelerations::Rnea => dd.o_a[k] = m.act_motion(&data.a_gf[k]),
            Accelerations::BiasPlus(qdd) => {
                let mut aq = dd.o_aq[p];
                for c in j.idx_v..j.idx_v + j.kind.nv() {
                    aq += dd.o_s[c] * qdd[c];
                }
                dd.o_aq[k] = aq;
                dd.o_a[k] = m.act_motion(&data.a[k]) + gravity_offset + aq;
            }
        }
        let y = OriginInertia::transformed(&b.inertia, m);
        if let Accelerations::BiasPlus(_) = acc {
            dd.f_q[k] = y.mul_motion(&dd.o_aq[k]);
        }
        dd.dycrb[k] = inertia_variation(&y, &vk);
        dd.ycrb[k] = y;
        if dd.has_applied {
            dd.gext[k] = applied_force_variation(dd, k);
        }
        let (vp, ap) = (dd.o_v[p], dd.o_a[p]);
        for c in 0..j.kind.nv() {
            let i = j.idx_v + c;
            let s = dd.o_s[i];
            let dv = vp.cross_motion(&s);
            let col = &mut dd.cols[i];
            col.s = s;
            col.dv_dq = dv;
            col.da_dq = ap.cross_motion(&s) + vp.cross_motion(&dv);
            col.da_dv = (vk + vp).cross_motion(&s);
        }
    }
}

/// G of body k: how the world-fixed forces applied to it change, seen from the body, when the
/// body moves by S: (ω × f, p × (ω × f)) summed over its points (and ω × m for pure moments),
/// as a matrix on S = (lin, ω): [0, −[F]×; 0, −[n]× − Σ p fᵀ + (Σ p·f) 1].
#[inline(always)]
fn applied_force_variation(dd: &DerivativeData, k: usize) -> AngularColumns {
    AngularColumns {
        t: -dd.ext_f[k],
        b: -skew(&dd.ext_m[k]) - dd.ext_pf[k] + Matrix3::identity() * dd.ext_pdotf[k],
    }
}

/// Leaf to root: each body's composites Y, Ẏ, G (children already added), its coordinates'
/// wrench variations, and the blocks of ∂τ/∂q, ∂τ/∂v (and M when `write_mass`) between its
/// coordinates and those of its subtree.
#[inline(always)]
fn backward_pass(model: &Model, data: &mut Data, dd: &mut DerivativeData, write_mass: bool) {
    data.size_mass_matrix(model.nv);
    let m = &mut data.mass_matrix;
    dd.dtau_dq.as_mut_slice().fill(0.0);
    dd.dtau_dv.as_mut_slice().fill(0.0);
    if write_mass {
        m.as_mut_slice().fill(0.0);
    }
    let bias_plus = !write_mass;
    let applied = dd.has_applied;
    for k in (1..model.nbodies()).rev() {
        let b = &model.bodies[k];
        let (y, dy) = (dd.ycrb[k], dd.dycrb[k]);
        let (c0, c1, end) = (
            b.joint.idx_v,
            b.joint.idx_v + b.joint.kind.nv(),
            dd.v_end[k],
        );
        for c in c0..c1 {
            let col = &mut dd.cols[c];
            col.df_da = y.mul_motion(&col.s);
            col.df_dq = dy.mul(&col.dv_dq) + y.mul_motion(&col.da_dq);
            col.df_dv = dy.mul(&col.s) + y.mul_motion(&col.da_dv);
            col.dyt_s = dy.tr_mul(&col.s);
            if applied {
                let g = &dd.gext[k];
                col.df_dq += g.mul(&col.s);
                col.gt_s = g.tr_mul(&col.s);
            }
        }
        for c in c0..c1 {
            let sc = dd.cols[c];
            // Rows below k (their composites already summed), column c.
            for r in c1..end {
                let rc = &dd.cols[r];
                let mut dq = sc.da_dq.dot(&rc.df_da) + rc.dyt_s.dot(&sc.dv_dq.ang);
                if applied {
                    dq += rc.gt_s.dot(&sc.s.ang);
                }
                dd.dtau_dq[(r, c)] = dq;
                dd.dtau_dv[(r, c)] = sc.da_dv.dot(&rc.df_da) + rc.dyt_s.dot(&sc.s.ang);
            }
            // Row c, the columns of k's subtree (k's own included).
            for r in c0..end {
                let rc = &dd.cols[r];
                dd.dtau_dq[(c, r)] = sc.s.dot(&rc.df_dq);
                dd.dtau_dv[(c, r)] = sc.s.dot(&rc.df_dv);
                if write_mass {
                    let mcr = sc.s.dot(&rc.df_da);
                    m[(c, r)] = mcr;
                    m[(r, c)] = mcr;
                }
            }
        }
        // Rows above k see the subtree's wrench F turn with it: S ×* F (F with q̈'s share,
        // its subtree's already summed, in the bias form).
        let p = b.parent;
        if bias_plus {
            let fq = dd.f_q[k];
            dd.o_f[k] += fq;
            if p != 0 {
                dd.f_q[p] += fq;
            }
        }
        let f = dd.o_f[k];
        for c in c0..c1 {
            let turn = dd.o_s[c].cross_force(&f);
            dd.cols[c].df_dq += turn;
        }
        if p != 0 {
            dd.ycrb[p] += y;
            dd.dycrb[p] += dy;
            if applied {
                let g = dd.gext[k];
                dd.gext[p] += g;
            }
        }
    }
}

/// The 6-vectors of one velocity coordinate in the backward pass (world axes).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Column {
    /// ᵒS.
    s: Motion,
    /// dV = v_P × S and dA = a_P × S + v_P × dV of ∂/∂δ; dA = (v_J + v_P) × S of ∂/∂v.
    dv_dq: Motion,
    da_dq: Motion,
    da_dv: Motion,
    /// Y S, Ẏ dV + Y dA + G S (then + S ×* F), Ẏ S + Y dA, with the composites of its body.
    df_da: Force,
    df_dq: Force,
    df_dv: Force,
    /// The angular parts of Ẏᵀ S and Gᵀ S (their linear parts are zero), what the rows of this
    /// coordinate need from the columns above it.
    dyt_s: Vector3<f64>,
    gt_s: Vector3<f64>,
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
    subtract_from_column(model, &dd.o_s, &mut dd.dtau_dq, body, j, w);
}

/// The same along velocity coordinate j (a force whose point moves with the velocity).
pub(crate) fn subtract_force_variation_v(
    model: &Model,
    dd: &mut DerivativeData,
    body: usize,
    j: usize,
    w: Force,
) {
    subtract_from_column(model, &dd.o_s, &mut dd.dtau_dv, body, j, w);
}

fn subtract_from_column(
    model: &Model,
    o_s: &[Motion],
    dtau: &mut DMatrix<f64>,
    body: usize,
    j: usize,
    w: Force,
) {
    let mut b = body;
    while b > 0 {
        let jb = &model.bodies[b].joint;
        for c in 0..jb.kind.nv() {
            let i = jb.idx_v + c;
            dtau[(i, j)] -= o_s[i].dot(&w);
        }
        b = model.bodies[b].parent;
    }
}
