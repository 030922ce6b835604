//! A velocity constraint written as an expression, f(q, v, t) = 0, possibly nonlinear in v
//! (seed 001, eq. 1): a servo constraint, a speed governor, Appell–Hamel's ż = a√(ẋ² + ẏ²).
//!
//! Chetaev's virtual displacements (the seed's eq. 22, its scheme for constraints homogeneous
//! in the velocities): the constraint force is Jᵀλ with J = ∂f/∂v (1 × nv). Differentiating
//! f along the motion gives the acceleration row
//!   ∂f/∂v q̈ = −(∂f/∂q q̇ + ∂f/∂t),   q̇ = G(q) v,
//! so γ = ∂f/∂q q̇ + ∂f/∂t (q̈ is the time derivative of v, as everywhere in the project; on a
//! free-flyer or planar base a configuration symbol's q̇ is its entry of G(q) v, e.g. ẋ of
//! `q:root_joint:x` is the world-axis velocity, not `vx_local`). φ = 0 (nonholonomic), and the
//! velocity residual reported and fed to the Baumgarte term K_d is f itself, not J v: the two
//! agree only for f homogeneous of degree 1 in v (Euler), and f is what must vanish.
//! λ: [generalized force × v-unit / f-unit]; Jᵀλ is a generalized force [N or N·m] per v.

use super::expression::{Expression, MAX_SYMBOLS, Source};
use super::{ConstraintRows, RowSink};
use crate::algorithm::Data;
use crate::model::Model;

/// f(q, v, t) = 0 with Chetaev's virtual displacements (one row).
#[derive(Clone, Debug)]
pub struct VelocityConstraint {
    /// The parsed expression with its partial derivatives.
    pub expression: Expression,
    /// Velocity index the scene asks to solve for in the embedded form (`dependent:`), if any.
    pub dependent: Option<usize>,
}

impl VelocityConstraint {
    /// f at (q, v, t).
    pub fn residual(&self, q: &[f64], v: &[f64], t: f64) -> f64 {
        let mut vals = [0.0; MAX_SYMBOLS];
        self.expression.values(q, v, t, &mut vals);
        self.expression.f(&vals)
    }

    /// Velocity indices f depends on.
    pub fn velocity_indices(&self) -> impl Iterator<Item = usize> + '_ {
        self.expression.symbols.iter().filter_map(|(_, s)| match s {
            Source::V { index } => Some(*index),
            _ => None,
        })
    }
}

impl ConstraintRows for VelocityConstraint {
    fn dim(&self) -> usize {
        1
    }

    fn fill(&self, model: &Model, _data: &Data, out: &mut RowSink) {
        let e = &self.expression;
        let mut vals = [0.0; MAX_SYMBOLS];
        e.values(out.q, out.v, out.t, &mut vals);
        let r = out.row0;
        out.clear_row(0);
        let mut gamma = 0.0;
        for (k, (_, src)) in e.symbols.iter().enumerate() {
            let d = e.df(k, &vals);
            match *src {
                Source::V { index } => out.j[(r, index)] += d,
                Source::Q { index, body } => {
                    gamma += d * Expression::qdot(model, body, index, out.q, out.v)
                }
                Source::Time => gamma += d,
            }
        }
        out.finish(r, 0.0, gamma, false);
        out.jv[r] = e.f(&vals);
        out.residual_given[r] = true;
    }
}
