//! Weld: the pose of frame A relative to frame B held at a target `b_m_a*` (identity by default).
//!
//! Translation rows: the point constraint between A's origin and B's material point at t*.
//! Rotation rows: φ = log₃(R_A (R_B R*)ᵀ), J = J_ωA − J_ωB, γ = α_A − α_B (world axes, q̈ = 0).
//! With `axes: local` every 3-row block is rotated into B's axes: J_B = R_Bᵀ J_W and
//! γ_B = R_Bᵀ γ_W − ω_B × (R_Bᵀ J_W v) (the derivative of the rotating basis).
//! λ: wrench on A at its origin [N, N·m] in the chosen axes (its opposite acts on B).

use super::{ConstraintRows, RowSink};
use crate::algorithm::{Data, ReferenceFrame, frame_jacobian, frame_placement};
use crate::model::Model;
use crate::spatial::SE3;
use nalgebra::{Matrix3, Vector3};

/// Pose of frame A relative to frame B held at `target`, on selected rows.
#[derive(Clone, Debug)]
pub struct WeldConstraint {
    /// Frame index of A.
    pub frame_a: usize,
    /// Frame index of B (0 = world).
    pub frame_b: usize,
    /// Target pose of A in B.
    pub target: SE3,
    /// Rows in world axes (false) or B's axes (true).
    pub local: bool,
    /// Selected rows 0..6 of `[x, y, z, rx, ry, rz]`.
    pub rows: Vec<usize>,
}

fn log3(r: &Matrix3<f64>) -> Vector3<f64> {
    SE3::new(*r, Vector3::zeros()).log().ang
}

impl ConstraintRows for WeldConstraint {
    fn dim(&self) -> usize {
        self.rows.len()
    }

    fn fill(&self, model: &Model, data: &Data, out: &mut RowSink) {
        let t = self.target.translation;
        let [d, dv, acc] = super::point::relative_point(
            model,
            data,
            (self.frame_a, &Vector3::zeros()),
            (self.frame_b, &t),
            out.j3,
            out.jtmp,
        );
        let o_m_a = frame_placement(model, data, self.frame_a);
        let o_m_b = frame_placement(model, data, self.frame_b);
        let e_rot = log3(&(o_m_a.rotation * (o_m_b.rotation * self.target.rotation).transpose()));
        let body_a = model.frames[self.frame_a].body;
        let body_b = model.frames[self.frame_b].body;
        let w = |b: usize| data.o_m_i[b].rotation * data.v[b].ang;
        let alpha = |b: usize| data.o_m_i[b].rotation * data.a[b].ang;
        let dw = w(body_a) - w(body_b);
        let g_rot = alpha(body_a) - alpha(body_b);
        // Angular Jacobian rows J_ωA − J_ωB (world) into j6 rows 3..6; J_ωB = 0 when B is fixed
        // in the world (a sole welded to the ground), so its Jacobian is not built.
        let nv = out.j.ncols();
        let b_moves = body_b != 0;
        if b_moves {
            frame_jacobian(model, data, self.frame_b, ReferenceFrame::World, out.j6);
            for c in 0..nv {
                for k in 0..3 {
                    out.jtmp[(k, c)] = out.j6[(3 + k, c)];
                }
            }
        }
        frame_jacobian(model, data, self.frame_a, ReferenceFrame::World, out.j6);
        for c in 0..nv {
            for k in 0..3 {
                if b_moves {
                    out.j6[(3 + k, c)] -= out.jtmp[(k, c)];
                }
                out.j6[(k, c)] = out.j3[(k, c)];
            }
        }
        let (mut phi, mut vel, mut gam) = ([d, e_rot], [dv, dw], [acc, g_rot]);
        if self.local {
            let rt = o_m_b.rotation.transpose();
            let wb = rt * w(body_b);
            for blk in 0..2 {
                phi[blk] = rt * phi[blk];
                vel[blk] = rt * vel[blk];
                gam[blk] = rt * gam[blk] - wb.cross(&vel[blk]);
                for c in 0..nv {
                    let col = Vector3::new(
                        out.j6[(3 * blk, c)],
                        out.j6[(3 * blk + 1, c)],
                        out.j6[(3 * blk + 2, c)],
                    );
                    let r = rt * col;
                    for k in 0..3 {
                        out.j6[(3 * blk + k, c)] = r[k];
                    }
                }
            }
        }
        for (k, &row) in self.rows.iter().enumerate() {
            let (blk, ax) = (row / 3, row % 3);
            out.set_row_from_j6(k, row, phi[blk][ax], gam[blk][ax], true);
        }
    }
}
