//! No side slip (knife edge): the velocity of a frame's origin along its own axis `e` is zero —
//! the seed's ẏ cos θ − ẋ sin θ = 0 for a differential drive with e = y of the base.
//!
//! Row: eᵀ v_F (v_F = linear velocity of the origin in F's axes), nonholonomic (φ = 0);
//! γ = eᵀ a_F(q̈ = 0), the body-frame derivative. λ: lateral force on F's origin along e [N].

use super::{ConstraintRows, RowResiduals, RowSink};
use crate::algorithm::{Data, ReferenceFrame, frame_jacobian};
use crate::model::Model;
use nalgebra::Vector3;

/// Knife edge: velocity of a frame's origin along the frame's own `axis` is zero.
#[derive(Clone, Debug)]
pub struct NoSideSlipConstraint {
    /// Frame index.
    pub frame: usize,
    /// Unit axis in the frame.
    pub axis: Vector3<f64>,
}

impl ConstraintRows for NoSideSlipConstraint {
    fn dim(&self) -> usize {
        1
    }

    fn fill(&self, model: &Model, data: &Data, out: &mut RowSink) {
        frame_jacobian(model, data, self.frame, ReferenceFrame::Local, out.j6);
        let f = &model.frames[self.frame];
        let a = f.placement.act_inv_motion(&data.a[f.body]);
        let r = out.row0;
        for c in 0..out.j.ncols() {
            out.j[(r, c)] = (0..3).map(|k| self.axis[k] * out.j6[(k, c)]).sum();
        }
        out.phi[r] = 0.0;
        out.gamma[r] = self.axis.dot(&a.lin);
        out.holonomic[r] = false;
    }

    /// J v = eᵀ v_F from the frame's twist.
    fn residuals(&self, model: &Model, data: &Data, out: RowResiduals) -> bool {
        let f = &model.frames[self.frame];
        let v = f.placement.act_inv_motion(&data.v[f.body]);
        (out.phi[0], out.jv[0], out.holonomic[0]) = (0.0, self.axis.dot(&v.lin), false);
        true
    }
}
