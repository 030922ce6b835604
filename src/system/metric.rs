//! The mass metric of a large tree without M: a projection in the metric M (the drift
//! projection's Δ = M⁻¹ Aᵀ (A M⁻¹ Aᵀ)⁺ r) on ABA's factorization M⁻¹ = Ψᵀ D⁻¹ Ψ, in O(n) per
//! row, where the dense metric factors M in O(n³) on a chain.

use super::System;
use crate::algorithm::innovations_product;

/// ABA's factors of M at one configuration, borrowed from the system that formed them.
pub struct TreeMetric<'a> {
    sys: &'a mut System,
}

impl System {
    /// Whether this system's dynamics go by ABA ([`crate::dynamics::takes_linear_path`]).
    pub fn takes_linear_path(&self) -> bool {
        self.linear
    }

    /// On a tree that takes the linear path ([`crate::dynamics::takes_linear_path`]): ABA's
    /// factors of M at q. None elsewhere, and where a pivot fails the dense path's checks (a
    /// link with no inertia of its own): the dense metric decides there. The factors stay valid
    /// until the next evaluation of the system.
    pub fn tree_metric(&mut self, q: &[f64]) -> Option<TreeMetric<'_>> {
        if !self.linear || q.len() != self.model.nq {
            return None;
        }
        self.tree
            .factor_metric(&self.model, &mut self.data, q)
            .then_some(TreeMetric { sys: self })
    }
}

impl TreeMetric<'_> {
    /// u = Ψ b (nv each).
    pub fn innovations(&mut self, b: &[f64], u: &mut [f64]) {
        let s = &mut *self.sys;
        s.tree.innovations(&s.model, &s.data, b, u);
    }

    /// aᵀ D⁻¹ b for two innovation vectors: (A M⁻¹ Aᵀ)'s entry for the rows whose innovations
    /// they are.
    pub fn product(&self, a: &[f64], b: &[f64]) -> f64 {
        innovations_product(&self.sys.model, &self.sys.data, a, b)
    }

    /// x = Ψᵀ D⁻¹ u: M⁻¹ b for u = Ψ b.
    pub fn from_innovations(&mut self, u: &[f64], x: &mut [f64]) {
        let s = &mut *self.sys;
        s.tree.from_innovations(&s.model, &s.data, u, x);
    }
}
