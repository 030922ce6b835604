//! Distance constraint `|p_A − p_B| = L`.
//!
//! With d = p_A − p_B and n = d/|d|: φ = |d| − L; J = nᵀ (J_pA − J_pB);
//! γ = nᵀ (a_A − a_B) + (|ḋ|² − (n·ḋ)²)/|d|. λ: force on A's point along n [N] (λ > 0 pushes A away
//! from B; −λ n acts on B).

use super::{ConstraintRows, RowSink};
use crate::algorithm::Data;
use crate::model::Model;
use nalgebra::Vector3;

/// Distance `|p_A − p_B| = L` between a point of frame A and a point of frame B.
#[derive(Clone, Debug)]
pub struct DistanceConstraint {
    /// Frame index of A.
    pub frame_a: usize,
    /// Point of A in A's frame [m].
    pub point_a: Vector3<f64>,
    /// Frame index of B (0 = world).
    pub frame_b: usize,
    /// Point of B in B's frame [m].
    pub point_b: Vector3<f64>,
    /// L [m], > 0.
    pub distance: f64,
}

impl ConstraintRows for DistanceConstraint {
    fn dim(&self) -> usize {
        1
    }

    fn fill(&self, model: &Model, data: &Data, out: &mut RowSink) {
        let [d, dd, acc] = super::point::relative_point(
            model,
            data,
            (self.frame_a, &self.point_a),
            (self.frame_b, &self.point_b),
            out.j3,
            out.jtmp,
        );
        let len = d.norm().max(f64::MIN_POSITIVE);
        let n: Vector3<f64> = d / len;
        let gamma = n.dot(&acc) + (dd.norm_squared() - n.dot(&dd).powi(2)) / len;
        out.set_row_dir(0, &n, len - self.distance, gamma, true);
    }
}
