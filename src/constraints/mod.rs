//! Constraints: holonomic (point, weld, distance, coupling) and nonholonomic (rolling,
//! no-side-slip, and `velocity`: f(q, v, t) = 0 written as an expression), each kind in one file
//! with its residual φ(q), Jacobian rows J and bias γ = J̇v (for `velocity`, γ = ∂f/∂q q̇ + ∂f/∂t).
//!
//! A `ConstraintSet` stacks the kinds' rows in scene order (`ranges[k]` are constraint k's rows):
//! `J(q) v = 0` at velocity level, `J q̈ + γ = 0` at acceleration level, and `φ(q) = 0` on holonomic
//! rows (φ is zero on nonholonomic rows).

mod build;
mod contact;
mod coupling;
mod distance;
mod expression;
mod expression_syntax;
mod expression_tape;
#[cfg(test)]
mod expression_tests;
mod forces;
mod kind;
mod no_side_slip;
mod point;
mod residuals;
mod rolling;
mod set;
mod spec;
mod velocity;
mod weld;

pub use contact::{BreakKind, Contact, ContactLimits, ContactState};
pub use coupling::CouplingConstraint;
pub use distance::DistanceConstraint;
pub use expression::{Expression, FUNCTIONS, MAX_SYMBOLS, RESERVED, Source};
pub use forces::{ConstraintForce, GeneralizedForce, constraint_forces, generalized_force_unit};
pub use kind::ConstraintKind;
pub use no_side_slip::NoSideSlipConstraint;
pub use point::PointConstraint;
pub use rolling::{
    ROLLING_ROW, RollingConstraint, rolling_direction, rolling_direction_rate,
    rolling_direction_rate_variation,
};
pub use set::{Constraint, ConstraintData, ConstraintSet};
pub use spec::{Axes, ConstraintSpec, LateralGrip, Row, VirtualDisplacements};
pub use velocity::VelocityConstraint;
pub use weld::WeldConstraint;

use crate::algorithm::Data;
use crate::model::Model;
use nalgebra::{DMatrix, DVector, Vector3};

/// The three things every constraint kind computes, at the state of the last kinematics pass
/// (placements, twists, and accelerations at q̈ = 0).
pub(crate) trait ConstraintRows {
    /// Number of rows.
    fn dim(&self) -> usize;
    /// Write J rows, φ and γ for rows `out.row0 .. out.row0 + dim`.
    fn fill(&self, model: &Model, data: &Data, out: &mut RowSink);
    /// φ, J v and the holonomic flag of each row straight from placements and twists (no J, no
    /// γ), for the residuals a sample reports; false for a kind without such a shortcut (its
    /// rows then come from `fill`).
    fn residuals(&self, _model: &Model, _data: &Data, _out: RowResiduals) -> bool {
        false
    }
}

/// Where [`ConstraintRows::residuals`] writes a constraint's rows (its own slices).
pub(crate) struct RowResiduals<'a> {
    pub phi: &'a mut [f64],
    pub jv: &'a mut [f64],
    pub holonomic: &'a mut [bool],
}

/// Where a constraint writes its rows, plus scratch Jacobians (allocated once).
pub(crate) struct RowSink<'a> {
    pub q: &'a [f64],
    pub v: &'a [f64],
    /// Time [s] (expression constraints may depend on it).
    pub t: f64,
    pub row0: usize,
    pub j: &'a mut DMatrix<f64>,
    pub phi: &'a mut DVector<f64>,
    pub gamma: &'a mut DVector<f64>,
    pub holonomic: &'a mut [bool],
    /// Velocity residual per row; a kind that sets `residual_given[r]` writes its own (f for
    /// `velocity`), every other row gets J v after the fill.
    pub jv: &'a mut DVector<f64>,
    pub residual_given: &'a mut [bool],
    /// 3 × nv scratch (point Jacobians).
    pub j3: &'a mut DMatrix<f64>,
    /// 3 × nv scratch.
    pub jtmp: &'a mut DMatrix<f64>,
    /// 6 × nv scratch (frame Jacobians).
    pub j6: &'a mut DMatrix<f64>,
}

impl RowSink<'_> {
    fn clear_row(&mut self, k: usize) {
        self.j.row_mut(self.row0 + k).fill(0.0);
    }
    /// Row k := row `src` of the 6 × nv scratch `j6`.
    fn set_row_from_j6(&mut self, k: usize, src: usize, phi: f64, gamma: f64, holonomic: bool) {
        let r = self.row0 + k;
        for c in 0..self.j.ncols() {
            self.j[(r, c)] = self.j6[(src, c)];
        }
        self.finish(r, phi, gamma, holonomic);
    }
    /// Row k := dirᵀ j3.
    fn set_row_dir(&mut self, k: usize, dir: &Vector3<f64>, phi: f64, gamma: f64, holonomic: bool) {
        let r = self.row0 + k;
        for c in 0..self.j.ncols() {
            self.j[(r, c)] =
                dir.x * self.j3[(0, c)] + dir.y * self.j3[(1, c)] + dir.z * self.j3[(2, c)];
        }
        self.finish(r, phi, gamma, holonomic);
    }
    fn finish(&mut self, r: usize, phi: f64, gamma: f64, holonomic: bool) {
        self.phi[r] = phi;
        self.gamma[r] = gamma;
        self.holonomic[r] = holonomic;
    }
}
