//! Articulated-body algorithm: forward dynamics `q̈ = M(q)⁻¹ (τ − h(q, v))` in O(nb).

use super::Data;
use crate::model::{Joint, JointKind, Model};
use crate::spatial::{Force, Motion};
use nalgebra::{DVector, Matrix6, Vector3, Vector6};

fn subspace_matrix(j: &Joint) -> Matrix6<f64> {
    let mut s = Matrix6::zeros();
    for k in 0..j.kind.nv() {
        s.set_column(k, &j.subspace[k].to_vector());
    }
    s
}

/// Inverse of the leading k × k block of a symmetric positive-definite `d` (zero elsewhere),
/// by its Cholesky factor; NaN throughout where the block is not positive definite (a massless
/// subtree), which q̈ then carries to the callers' checks.
fn inverse_leading_block(d: &Matrix6<f64>, k: usize) -> Matrix6<f64> {
    // L (lower) in `l`, then L⁻¹ in place, then D⁻¹ = L⁻ᵀ L⁻¹.
    let mut l = Matrix6::zeros();
    for j in 0..k {
        let mut djj = d[(j, j)];
        for m in 0..j {
            djj -= l[(j, m)] * l[(j, m)];
        }
        if djj.is_nan() || djj <= 0.0 {
            return Matrix6::from_element(f64::NAN);
        }
        let ljj = djj.sqrt();
        l[(j, j)] = ljj;
        for r in j + 1..k {
            let mut x = d[(r, j)];
            for m in 0..j {
                x -= l[(r, m)] * l[(j, m)];
            }
            l[(r, j)] = x / ljj;
        }
    }
    let mut w = Matrix6::zeros();
    for j in 0..k {
        w[(j, j)] = 1.0 / l[(j, j)];
        for r in j + 1..k {
            let mut x = 0.0;
            for m in j..r {
                x -= l[(r, m)] * w[(m, j)];
            }
            w[(r, j)] = x / l[(r, r)];
        }
    }
    let mut inv = Matrix6::zeros();
    for a in 0..k {
        for b in 0..=a {
            let mut x = 0.0;
            for m in a..k {
                x += w[(m, a)] * w[(m, b)];
            }
            inv[(a, b)] = x;
            inv[(b, a)] = x;
        }
    }
    inv
}

/// q̈ = FD(q, v, τ) into `data.qdd` (Featherstone's three passes, body frames, gravity as a base
/// acceleration −g). A massless leaf joint makes its articulated inertia singular: q̈ then holds
/// NaN, which callers check (the constrained solvers do not use ABA).
pub fn aba<'a>(
    model: &Model,
    data: &'a mut Data,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) -> &'a DVector<f64> {
    let nb = model.nbodies();
    for i in 1..nb {
        let b = &model.bodies[i];
        let j = &b.joint;
        // (Not `kinematics::place`: its fast path measured 3–6 % slower inside this loop.)
        let li = j
            .kind
            .placed(&b.placement, &q[j.idx_q..j.idx_q + j.kind.nq()]);
        data.li_m_i[i] = li;
        data.o_m_i[i] = data.o_m_i[b.parent].compose(&li);
        let mut vj = Motion::zero();
        for k in 0..j.kind.nv() {
            vj += j.subspace[k] * v[j.idx_v + k];
        }
        let vi = li.act_inv_motion(&data.v[b.parent]) + vj;
        data.v[i] = vi;
        data.c[i] = vi.cross_motion(&vj);
        data.ia[i] = b.inertia.matrix();
        data.pa[i] = vi.cross_force(&b.inertia.mul_motion(&vi)).to_vector();
    }
    for i in (1..nb).rev() {
        let b = &model.bodies[i];
        let j = &b.joint;
        let nvj = j.kind.nv();
        let c = data.c[i].to_vector();
        // A body on the world passes nothing on: its U, D⁻¹ and u only.
        let root = b.parent == 0;
        let (ia, pa) = if nvj == 1 {
            // U = IA S, D = Sᵀ U and Sᵀ p; for S = ±e (an aligned revolute axis) a column and
            // two entries, the same numbers as the products (their other terms are exact zeros).
            let (u, d, sp) = match &j.kind {
                JointKind::Revolute {
                    aligned: Some((k, sign)),
                    ..
                } => (
                    data.ia[i].column(3 + k) * *sign,
                    data.ia[i][(3 + k, 3 + k)],
                    data.pa[i][3 + k] * *sign,
                ),
                _ => {
                    let s = j.subspace[0].to_vector();
                    let u = data.ia[i] * s;
                    (u, s.dot(&u), s.dot(&data.pa[i]))
                }
            };
            let dinv = 1.0 / d;
            let ui = tau[j.idx_v] - sp;
            data.u_mat[i].set_column(0, &u);
            data.d_inv[i][(0, 0)] = dinv;
            data.u_vec[i][0] = ui;
            if root {
                continue;
            }
            let ia = data.ia[i] - u * u.transpose() * dinv;
            let pa = data.pa[i] + ia * c + u * (dinv * ui);
            (ia, pa)
        } else {
            // A free-flyer's S is the identity: U = D = IA.
            let (u, d, stp) = if matches!(j.kind, JointKind::FreeFlyer) {
                (data.ia[i], data.ia[i], data.pa[i])
            } else {
                let s = subspace_matrix(j);
                let u = data.ia[i] * s;
                (u, s.transpose() * u, s.transpose() * data.pa[i])
            };
            let dinv = inverse_leading_block(&d, nvj);
            let mut ui = Vector6::zeros();
            for k in 0..nvj {
                ui[k] = tau[j.idx_v + k] - stp[k];
            }
            data.u_mat[i] = u;
            data.d_inv[i] = dinv;
            data.u_vec[i] = ui;
            if root {
                continue;
            }
            let ia = data.ia[i] - u * dinv * u.transpose();
            let pa = data.pa[i] + ia * c + u * (dinv * ui);
            (ia, pa)
        };
        let x = &data.li_m_i[i];
        let iap = x.act_inertia_matrix(&ia);
        data.ia[b.parent] += iap;
        let fp = x.act_force(&Force::from_vector(&pa)).to_vector();
        data.pa[b.parent] += fp;
    }
    data.a_gf[0] = Motion::new(-model.gravity, Vector3::zeros());
    for i in 1..nb {
        let b = &model.bodies[i];
        let j = &b.joint;
        let nvj = j.kind.nv();
        let ap = data.li_m_i[i].act_inv_motion(&data.a_gf[b.parent]) + data.c[i];
        let apv = ap.to_vector();
        let mut ai = ap;
        if nvj == 1 {
            let u = data.u_mat[i].column(0);
            let qdd = data.d_inv[i][(0, 0)] * (data.u_vec[i][0] - u.dot(&apv));
            data.qdd[j.idx_v] = qdd;
            ai += j.subspace[0] * qdd;
        } else {
            let rhs = data.u_vec[i] - data.u_mat[i].transpose() * apv;
            let qdd = data.d_inv[i] * rhs;
            for k in 0..nvj {
                data.qdd[j.idx_v + k] = qdd[k];
                ai += j.subspace[k] * qdd[k];
            }
        }
        data.a_gf[i] = ai;
    }
    &data.qdd
}

/// The innovations u = Ψ b of ABA's factorization M⁻¹ = Ψᵀ D⁻¹ Ψ (Rodriguez, Jain and
/// Kreutz-Delgado) with the articulated-body factors of the last [`aba`] call at q (U = IA S,
/// D⁻¹ and the joint placements in `data`): ABA's force pass at zero velocity and gravity,
/// O(nb), allocation-free. `p` is a workspace of nb spatial vectors. With the rows of a
/// constraint Jacobian as `b`, the Schur complement J M⁻¹ Jᵀ is a Gram matrix of the u's in
/// the D⁻¹ metric ([`innovations_product`]): positive semi-definite to rounding, as the dense
/// path's Yᵀ Y is, so a dependent row's pivot comes out at rounding level.
pub fn aba_innovations(
    model: &Model,
    data: &Data,
    b: &[f64],
    u: &mut [f64],
    p: &mut [Vector6<f64>],
) {
    let nb = model.nbodies();
    p[..nb].fill(Vector6::zeros());
    // Each joint's u = b − Sᵀ p; its subtree passes p + U D⁻¹ u to the parent.
    for i in (1..nb).rev() {
        let body = &model.bodies[i];
        let j = &body.joint;
        let nvj = j.kind.nv();
        let mut passed = p[i];
        if nvj == 1 {
            let ui = b[j.idx_v] - j.subspace[0].to_vector().dot(&p[i]);
            u[j.idx_v] = ui;
            passed += data.u_mat[i].column(0) * (data.d_inv[i][(0, 0)] * ui);
        } else {
            let mut ui = Vector6::zeros();
            for k in 0..nvj {
                ui[k] = b[j.idx_v + k] - j.subspace[k].to_vector().dot(&p[i]);
                u[j.idx_v + k] = ui[k];
            }
            passed += data.u_mat[i] * (data.d_inv[i] * ui);
        }
        if body.parent != 0 {
            let f = data.li_m_i[i].act_force(&Force::from_vector(&passed));
            p[body.parent] += f.to_vector();
        }
    }
}

/// x = Ψᵀ D⁻¹ u, so that x = M⁻¹ b for u = [`aba_innovations`] of b: ABA's acceleration pass
/// at zero velocity and gravity, O(nb). `acc` is a workspace of nb spatial vectors.
pub fn aba_from_innovations(
    model: &Model,
    data: &Data,
    u: &[f64],
    x: &mut [f64],
    acc: &mut [Vector6<f64>],
) {
    let nb = model.nbodies();
    acc[0] = Vector6::zeros();
    for i in 1..nb {
        let body = &model.bodies[i];
        let j = &body.joint;
        let nvj = j.kind.nv();
        let ap = data.li_m_i[i]
            .act_inv_motion(&Motion::from_vector(&acc[body.parent]))
            .to_vector();
        let mut ai = ap;
        if nvj == 1 {
            let um = data.u_mat[i].column(0);
            let qdd = data.d_inv[i][(0, 0)] * (u[j.idx_v] - um.dot(&ap));
            x[j.idx_v] = qdd;
            ai += j.subspace[0].to_vector() * qdd;
        } else {
            let mut rhs = Vector6::zeros();
            let utap = data.u_mat[i].transpose() * ap;
            for k in 0..nvj {
                rhs[k] = u[j.idx_v + k] - utap[k];
            }
            let qdd = data.d_inv[i] * rhs;
            for k in 0..nvj {
                x[j.idx_v + k] = qdd[k];
                ai += j.subspace[k].to_vector() * qdd[k];
            }
        }
        acc[i] = ai;
    }
}

/// aᵀ D⁻¹ b over the joints for two innovation vectors (nv each) of the last [`aba`]:
/// J M⁻¹ Jᵀ's entry for two rows of J.
pub fn innovations_product(model: &Model, data: &Data, a: &[f64], b: &[f64]) -> f64 {
    let mut sum = 0.0;
    for (i, body) in model.bodies.iter().enumerate().skip(1) {
        let j = &body.joint;
        let (k0, nvj) = (j.idx_v, j.kind.nv());
        if nvj == 1 {
            sum += a[k0] * data.d_inv[i][(0, 0)] * b[k0];
            continue;
        }
        for r in 0..nvj {
            for c in 0..nvj {
                sum += a[k0 + r] * data.d_inv[i][(r, c)] * b[k0 + c];
            }
        }
    }
    sum
}
