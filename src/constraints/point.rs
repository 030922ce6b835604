//! Point constraint: point `p_a` of frame A held at point `p_b` of frame B (or the world).
//!
//! φ = p_A(q) − p_B(q) (world axes, selected rows) [m]; J = J_pA − J_pB (world-axes point
//! Jacobians); γ = a_A − a_B, the classical accelerations of the two material points at q̈ = 0.
//! λ: force exerted on A's point by the constraint [N], world axes (−λ acts on B).

use super::{ConstraintRows, RowResiduals, RowSink};
use crate::algorithm::{
    Data, point_classical_acceleration, point_jacobian, point_jacobian_rows,
    point_jacobian_rows_subtract, point_position, point_velocity,
};
use crate::model::Model;
use nalgebra::{DMatrix, Vector3};

/// Point `point_a` of frame A held at point `point_b` of frame B, on selected world axes.
#[derive(Clone, Debug)]
pub struct PointConstraint {
    /// Frame index of A.
    pub frame_a: usize,
    /// Point of A in A's frame [m].
    pub point_a: Vector3<f64>,
    /// Frame index of B (0 = world).
    pub frame_b: usize,
    /// Point of B in B's frame [m].
    pub point_b: Vector3<f64>,
    /// Selected world axes (0 = x, 1 = y, 2 = z).
    pub axes: Vec<usize>,
    /// The one row pushes but never pulls (λ ≥ 0), for the acceleration envelope.
    pub unilateral: bool,
    /// Coulomb coefficient μ of a ground contact (‖λ_xy‖ ≤ μ λ_z), for the acceleration envelope.
    pub friction: Option<f64>,
}

/// Relative position, velocity and classical acceleration (q̈ = 0) of A's point w.r.t. B's, and the
/// 3 × nv relative Jacobian in `jrel`.
pub(crate) fn relative_point(
    model: &Model,
    data: &Data,
    a: (usize, &Vector3<f64>),
    b: (usize, &Vector3<f64>),
    jrel: &mut DMatrix<f64>,
    jtmp: &mut DMatrix<f64>,
) -> [Vector3<f64>; 3] {
    point_jacobian(model, data, a.0, a.1, jrel, 0);
    let (pa, va, aa) = (
        point_position(model, data, a.0, a.1),
        point_velocity(model, data, a.0, a.1),
        point_classical_acceleration(model, data, a.0, a.1),
    );
    if model.frames[b.0].body == 0 {
        // B is fixed in the world: no Jacobian, velocity or acceleration to subtract.
        return [pa - point_position(model, data, b.0, b.1), va, aa];
    }
    point_jacobian(model, data, b.0, b.1, jtmp, 0);
    for r in 0..3 {
        for c in 0..jrel.ncols() {
            jrel[(r, c)] -= jtmp[(r, c)];
        }
    }
    [
        pa - point_position(model, data, b.0, b.1),
        va - point_velocity(model, data, b.0, b.1),
        aa - point_classical_acceleration(model, data, b.0, b.1),
    ]
}

impl ConstraintRows for PointConstraint {
    fn dim(&self) -> usize {
        self.axes.len()
    }

    fn fill(&self, model: &Model, data: &Data, out: &mut RowSink) {
        // The selected rows of A's point Jacobian straight into J (the rolling rows' one pass,
        // with unit directions), B's subtracted in place: no 3 × nv scratch to fill and copy
        // row by row. The same numbers: eₐₓᵀ J_p is J_p's row ax exactly (the zero products
        // add nothing).
        let pa = point_position(model, data, self.frame_a, &self.point_a);
        let pb = point_position(model, data, self.frame_b, &self.point_b);
        let d = pa - pb;
        let mut acc = point_classical_acceleration(model, data, self.frame_a, &self.point_a);
        let mut dirs = [Vector3::zeros(); 3];
        for (dir, &ax) in dirs.iter_mut().zip(&self.axes) {
            dir[ax] = 1.0;
        }
        let dirs = &dirs[..self.axes.len()];
        let body_a = model.frames[self.frame_a].body;
        point_jacobian_rows(model, data, body_a, &pa, dirs, out.j, out.row0);
        let body_b = model.frames[self.frame_b].body;
        // B fixed in the world (a foot, a held tool): no Jacobian or acceleration to subtract.
        if body_b != 0 {
            acc -= point_classical_acceleration(model, data, self.frame_b, &self.point_b);
            point_jacobian_rows_subtract(model, data, body_b, &pb, dirs, out.j, out.row0);
        }
        for (k, &ax) in self.axes.iter().enumerate() {
            out.finish(out.row0 + k, d[ax], acc[ax], true);
        }
    }

    /// φ and J v = v_A − v_B (the two material points' world velocities) from placements and
    /// twists: a sample's residuals without the Jacobian and γ.
    fn residuals(&self, model: &Model, data: &Data, out: RowResiduals) -> bool {
        let d = point_position(model, data, self.frame_a, &self.point_a)
            - point_position(model, data, self.frame_b, &self.point_b);
        let mut dv = point_velocity(model, data, self.frame_a, &self.point_a);
        if model.frames[self.frame_b].body != 0 {
            dv -= point_velocity(model, data, self.frame_b, &self.point_b);
        }
        for (k, &ax) in self.axes.iter().enumerate() {
            (out.phi[k], out.jv[k], out.holonomic[k]) = (d[ax], dv[ax], true);
        }
        true
    }
}
