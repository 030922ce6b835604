//! Frame and point Jacobians (after `forward_kinematics_pos`).

use super::Data;
use crate::model::Model;
use nalgebra::{DMatrix, Vector3};

/// Where a Jacobian's twist is expressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceFrame {
    /// Spatial twist at the world origin, world axes.
    World,
    /// Twist of the frame, frame axes.
    Local,
    /// Twist of the frame origin, world axes.
    LocalWorldAligned,
}

/// 6 × nv Jacobian of `frame`, rows `[lin; ang]`: `twist = J v`. Columns of joints that do not
/// support the frame are zero.
pub fn frame_jacobian(
    model: &Model,
    data: &Data,
    frame: usize,
    rf: ReferenceFrame,
    j: &mut DMatrix<f64>,
) {
    j.as_mut_slice().fill(0.0);
    let f = &model.frames[frame];
    let o_m_f = data.o_m_i[f.body].compose(&f.placement);
    let mut i = f.body;
    while i != 0 {
        let jt = &model.bodies[i].joint;
        for k in 0..jt.kind.nv() {
            let col = data.o_m_i[i].act_motion(&jt.subspace[k]);
            let col = match rf {
                ReferenceFrame::World => col,
                ReferenceFrame::Local => o_m_f.act_inv_motion(&col),
                ReferenceFrame::LocalWorldAligned => crate::spatial::Motion::new(
                    col.lin - o_m_f.translation.cross(&col.ang),
                    col.ang,
                ),
            };
            let c = jt.idx_v + k;
            for r in 0..3 {
                j[(r, c)] = col.lin[r];
                j[(r + 3, c)] = col.ang[r];
            }
        }
        i = model.bodies[i].parent;
    }
}

/// 3 × nv world-axes linear-velocity Jacobian of the material point `p` (in `frame`) written into
/// rows `row..row+3` of `j` (other columns of those rows set to zero).
pub fn point_jacobian(
    model: &Model,
    data: &Data,
    frame: usize,
    p: &Vector3<f64>,
    j: &mut DMatrix<f64>,
    row: usize,
) {
    for r in 0..3 {
        j.row_mut(row + r).fill(0.0);
    }
    let f = &model.frames[frame];
    let pw = data.o_m_i[f.body].act_point(&f.placement.act_point(p));
    for_each_point_column(model, data, f.body, &pw, |c, lin| {
        for r in 0..3 {
            j[(row + r, c)] = lin[r];
        }
    });
}

/// Rows `row0 + r` of `j` := `dirs[r]ᵀ J_p`, J_p the 3 × nv world-axes linear-velocity Jacobian
/// of the material point of `body` at the world position `pw` [m] (other columns of those
/// rows set to zero): `dirᵀ (ᵒS.lin + ᵒS.ang × pw)` per supporting column. What a constraint on
/// a point's velocity along given directions needs, without the 3 × nv intermediate and a
/// product by it (the rolling rows: one pass instead of three).
pub fn point_jacobian_rows(
    model: &Model,
    data: &Data,
    body: usize,
    pw: &Vector3<f64>,
    dirs: &[Vector3<f64>],
    j: &mut DMatrix<f64>,
    row0: usize,
) {
    // Column-major storage, entry (r, c) at c·nrows + r: the rows' entries of one column are
    // adjacent.
    let nr = j.nrows();
    let s = j.as_mut_slice();
    for c in 0..model.nv {
        s[c * nr + row0..c * nr + row0 + dirs.len()].fill(0.0);
    }
    for_each_point_column(model, data, body, pw, |c, lin| {
        let col = c * nr + row0;
        for (r, d) in dirs.iter().enumerate() {
            // Written out: nalgebra's generic `dot` left a loop here.
            s[col + r] = d.x * lin.x + d.y * lin.y + d.z * lin.z;
        }
    });
}

/// Rows `row0 + r` of `j` −= `dirs[r]ᵀ J_p` (J_p as in [`point_jacobian_rows`]; the columns of
/// joints that do not support `body` are left as they are): the second point of a constraint
/// between two bodies, after the first's [`point_jacobian_rows`].
pub fn point_jacobian_rows_subtract(
    model: &Model,
    data: &Data,
    body: usize,
    pw: &Vector3<f64>,
    dirs: &[Vector3<f64>],
    j: &mut DMatrix<f64>,
    row0: usize,
) {
    let nr = j.nrows();
    let s = j.as_mut_slice();
    for_each_point_column(model, data, body, pw, |c, lin| {
        let col = c * nr + row0;
        for (r, d) in dirs.iter().enumerate() {
            s[col + r] -= d.x * lin.x + d.y * lin.y + d.z * lin.z;
        }
    });
}

/// `tau += J_pᵀ f` (nv), J_p the world-axes linear-velocity Jacobian of the material point of
/// `body` at the world position `pw` [m]: the generalized force of the force `f` [N, world
/// axes] applied there, in one walk of the supporting chain (no 3 × nv intermediate).
pub fn point_jacobian_transpose_add(
    model: &Model,
    data: &Data,
    body: usize,
    pw: &Vector3<f64>,
    f: &Vector3<f64>,
    tau: &mut [f64],
) {
    for_each_point_column(model, data, body, pw, |c, lin| {
        tau[c] += lin.x * f.x + lin.y * f.y + lin.z * f.z;
    });
}

/// Calls `f(c, v)` for each velocity coordinate c of the joints that support `body`, v the
/// world-axes linear velocity [m/s per unit of v_c] of the material point of `body` at the
/// world position `pw` [m]: column c of its point Jacobian (the other columns are zero). The one
/// walk of the chain behind [`point_jacobian`] and [`point_jacobian_rows`].
#[inline(always)]
fn for_each_point_column(
    model: &Model,
    data: &Data,
    body: usize,
    pw: &Vector3<f64>,
    mut f: impl FnMut(usize, &Vector3<f64>),
) {
    let mut i = body;
    while i != 0 {
        let jt = &model.bodies[i].joint;
        let o = &data.o_m_i[i];
        // ᵒS.lin + ᵒS.ang × pw = R S.lin + ω × (pw − t), with ω = R S.ang.
        let arm = pw - o.translation;
        for k in 0..jt.kind.nv() {
            let sk = &jt.subspace[k];
            let ang = o.rotation * sk.ang;
            let lin = o.rotation * sk.lin + ang.cross(&arm);
            f(jt.idx_v + k, &lin);
        }
        i = model.bodies[i].parent;
    }
}
