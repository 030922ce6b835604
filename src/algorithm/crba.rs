//! Composite rigid-body algorithm: the joint-space inertia matrix M(q).

use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{Motion, OriginInertia};
use nalgebra::DMatrix;

/// M(q)'s lower triangle (diagonal included) into `data.mass_matrix`; the strict upper triangle is
/// not written (it keeps whatever it held), as compiled Pinocchio's `crba` writes one triangle.
/// Every factorization here reads the lower triangle only (the LTL factor, the dense Cholesky);
/// [`crba_full`] mirrors it for products with M.
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
    data.size_mass_matrix(model.nv);
    kinematics_and_sweeps(model, data, q);
    &data.mass_matrix
}

/// M(q), both triangles: [`crba`] and its lower triangle mirrored.
pub fn crba_full<'a>(model: &Model, data: &'a mut Data, q: &[f64]) -> &'a DMatrix<f64> {
    crba(model, data, q);
    data.mass_matrix.fill_upper_triangle_with_lower_triangle();
    &data.mass_matrix
}

crate::linalg::wide_fn! {
/// The placements at q, then both sweeps, in one AVX2 build where the CPU has it (the same
/// arithmetic, so the same numbers; its three-operand instructions spare the register copies
/// of the SSE2 build). (One loop for the kinematics and the forward sweep measured 15–25 %
/// slower.)
fn kinematics_and_sweeps(model: &Model, data: &mut Data, q: &[f64]) {
    for i in 1..model.nbodies() {
        super::kinematics::place(model, data, i, q);
    }
    sweeps_by_base(model, data);
}
}

/// [`crba`] (the lower triangle) reusing the placements `o_m_i` of a kinematics pass at the same q.
pub(crate) fn crba_after_kinematics<'a>(model: &Model, data: &'a mut Data) -> &'a DMatrix<f64> {
    data.size_mass_matrix(model.nv);
    sweeps_wide(model, data);
    &data.mass_matrix
}

/// [`crba_full`] (both triangles) reusing the placements `o_m_i` of a kinematics pass at the
/// same q.
pub(crate) fn crba_full_after_kinematics<'a>(
    model: &Model,
    data: &'a mut Data,
) -> &'a DMatrix<f64> {
    crba_after_kinematics(model, data);
    data.mass_matrix.fill_upper_triangle_with_lower_triangle();
    &data.mass_matrix
}

crate::linalg::wide_fn! {
/// [`sweeps_by_base`] in an AVX2 build where the CPU has it.
fn sweeps_wide(model: &Model, data: &mut Data) {
    sweeps_by_base(model, data);
}
}

/// The sweeps built for the model's base kind.
#[inline(always)]
fn sweeps_by_base(model: &Model, data: &mut Data) {
    let free_flyer = matches!(
        model.bodies.get(1).map(|b| (&b.joint.kind, b.joint.idx_v)),
        Some((JointKind::FreeFlyer, 0))
    );
    if free_flyer {
        sweeps::<true>(model, data);
    } else {
        sweeps::<false>(model, data);
    }
}

/// Both sweeps, compiled once per base kind: a fixed base's checks of the free-flyer's
/// coordinates fold away (one shared build measured +2–3 % instructions on ur5 and panda).
#[inline(always)]
fn sweeps<const FREE_FLYER: bool>(model: &Model, data: &mut Data) {
    // Velocity coordinates 0..6 of a free-flyer base (body 1), or none.
    let base_nv = if FREE_FLYER { 6 } else { 0 };
    let mut first = 1;
    if FREE_FLYER {
        // The base's block comes from the composite inertia (`base_rows`), its own inertia only.
        data.ycrb[1] = OriginInertia::transformed(&model.bodies[1].inertia, &data.o_m_i[1]);
        first = 2;
    }
    for i in first..model.nbodies() {
        forward(model, data, i);
    }
    backward(model, data, base_nv);
    if FREE_FLYER {
        base_rows(model, data);
    }
}

/// M's diagonal into `diag` (nv) from the placements `o_m_i` of a kinematics pass at q: the
/// composite inertias' sweep alone, O(nb), without M's off-diagonal entries (whose count grows
/// with the depth of the tree: n²/2 on a chain). `M_kk = ᵒS_kᵀ ᵒY_i ᵒS_k` with i k's body.
pub(crate) fn mass_diagonal_after_kinematics(model: &Model, data: &mut Data, diag: &mut [f64]) {
    for i in 1..model.nbodies() {
        forward(model, data, i);
    }
    for i in (1..model.nbodies()).rev() {
        let b = &model.bodies[i];
        let y = data.ycrb[i];
        for c in b.joint.idx_v..b.joint.idx_v + b.joint.kind.nv() {
            diag[c] = data.o_s[c].dot(&y.mul_motion(&data.o_s[c]));
        }
        if b.parent != 0 {
            data.ycrb[b.parent] += y;
        }
    }
}

/// Body i's inertia and subspace columns in world axes.
#[inline(always)]
fn forward(model: &Model, data: &mut Data, i: usize) {
    let b = &model.bodies[i];
    let j = &b.joint;
    let o_m_i = &data.o_m_i[i];
    data.ycrb[i] = OriginInertia::transformed(&b.inertia, o_m_i);
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

/// The composite inertias from the leaves to the root, and M's lower triangle but a free-flyer
/// base's rows.
#[inline(always)]
fn backward(model: &Model, data: &mut Data, base_nv: usize) {
    let nv = model.nv;
    let m = data.mass_matrix.as_mut_slice();
    let (o_s, f_crb) = (&data.o_s, &mut data.f_crb);
    for i in (1..model.nbodies()).rev() {
        let b = &model.bodies[i];
        let ji = &b.joint;
        let y = data.ycrb[i];
        let cols = ji.idx_v.max(base_nv)..ji.idx_v + ji.kind.nv();
        // The empty `black_box`es keep these loops scalar: vectorized, their set-up on runs
        // of 1–7 entries cost more than it saved (the rows' ur5 +4 %, panda +5 %; the forces'
        // solo12 and talos_reduced +3 % instructions).
        for c in cols.clone() {
            f_crb[c] = y.mul_motion(&o_s[c]);
            std::hint::black_box(());
        }
        // Row r against every column r moves (its subtree, one contiguous range of forces
        // already computed): the lower triangle's column r, contiguous in memory.
        for r in cols {
            let s_r = o_s[r];
            let end = model.v_subtree_end[r];
            let (col, forces) = (&mut m[r * nv + r..r * nv + end], &f_crb[r..end]);
            for k in 0..forces.len() {
                col[k] = s_r.dot(&forces[k]);
                std::hint::black_box(());
            }
        }
        if b.parent != 0 {
            data.ycrb[b.parent] += y;
        }
    }
}

crate::linalg::wide_fn! {
/// A free-flyer base's six columns of the lower triangle: its own block, the whole robot's
/// composite inertia in the base frame `[[m 1, −[h]×], [[h]×, I]]` about the base origin, and
/// each other column's force in the base frame as row c. Out of line, so that the fixed-base
/// robots' sweeps compile without it; in an AVX2 build where the CPU has it.
#[inline(never)]
fn base_rows(model: &Model, data: &mut Data) {
    let nv = model.nv;
    let m = data.mass_matrix.as_mut_slice();
    let o_m_b = &data.o_m_i[1];
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
        m[c * nv + c..c * nv + 6].copy_from_slice(&col[c..]);
    }
    // Column c's base rows: its force in the base frame, transformed in place, then written
    // as row c of the first six columns, a contiguous run in each.
    for f in data.f_crb.iter_mut().skip(6) {
        *f = o_m_b.act_inv_force(f);
    }
    let forces = &data.f_crb[6..];
    for (r, col) in m.chunks_exact_mut(nv).take(6).enumerate() {
        let row = col[6..].iter_mut().zip(forces);
        if r < 3 {
            row.for_each(|(x, fb)| *x = fb.lin[r]);
        } else {
            row.for_each(|(x, fb)| *x = fb.ang[r - 3]);
        }
    }
}
}
