//! Joint coupling `a·q_i + b·q_j = c` (every URDF `<mimic>` becomes one:
//! `q_joint − multiplier·q_mimicked = offset`).
//!
//! φ = a q_i + b q_j − c; J = a e_i + b e_j; γ = 0. λ: generalized force per unit of the row; the
//! joint efforts it applies are (a λ, b λ) [N·m or N].

use super::{ConstraintRows, RowSink};
use crate::algorithm::Data;
use crate::model::Model;

/// `a·q_i + b·q_j = c` between two 1-DOF joints.
#[derive(Clone, Debug)]
pub struct CouplingConstraint {
    /// (configuration index, velocity index) of joint i and joint j.
    pub qi: usize,
    /// Velocity index of joint i.
    pub vi: usize,
    /// Configuration index of joint j.
    pub qj: usize,
    /// Velocity index of joint j.
    pub vj: usize,
    /// Coefficient of q_i.
    pub a: f64,
    /// Coefficient of q_j.
    pub b: f64,
    /// Right-hand side [rad or m].
    pub c: f64,
}

impl ConstraintRows for CouplingConstraint {
    fn dim(&self) -> usize {
        1
    }

    fn fill(&self, _model: &Model, _data: &Data, out: &mut RowSink) {
        let q = out.q;
        let phi = self.a * q[self.qi] + self.b * q[self.qj] - self.c;
        out.clear_row(0);
        out.j[(out.row0, self.vi)] += self.a;
        out.j[(out.row0, self.vj)] += self.b;
        out.phi[out.row0] = phi;
        out.gamma[out.row0] = 0.0;
        out.holonomic[out.row0] = true;
    }
}
