//! Constrained forward dynamics: `M(q) q̈ + h(q, v) = τ + Jᵀλ` with `J q̈ = −γ − K_d J v − K_p φ`.
//!
//! Two formulations give the same q̈:
//! - [`multipliers`]: the KKT system `[M Jᵀ; J 0][q̈; −λ] = [τ − h; −γ − K_d J v − K_p φ]` through
//!   a Cholesky factor of M and the Schur complement `J M⁻¹ Jᵀ`, returning λ;
//! - [`embedded`]: Voronets' multiplier-free form, dependent velocities solved from the
//!   constraints, `(NᵀMN) q̈_i = Nᵀ(τ − h − M q̈_p)` in the independent coordinates only.
//!
//! `Formulation::Auto` uses the embedded form unless constraint forces are asked for. Without
//! constraint rows both are q̈ = M⁻¹(τ − h), which [`tree`] computes in O(n) for large trees;
//! with m rows, [`tree_multipliers`] computes the multiplier form there in O(n·m + m³).

mod embedded;
mod multipliers;
mod partition;
mod tree;
mod tree_multipliers;

pub use embedded::{EmbeddedWorkspace, embedded_forward_dynamics};
pub use multipliers::{KktOptions, KktWorkspace, constrained_forward_dynamics};
pub use partition::{
    Partition, PartitionWorkspace, partition, partition_into, partition_preferring,
};
pub use tree::{LINEAR_MIN_MEAN_DEPTH, TreeWorkspace, takes_linear_path, tree_forward_dynamics};
pub use tree_multipliers::{TreeKktWorkspace, tree_constrained_forward_dynamics};

use serde::{Deserialize, Serialize};

/// Whether constraint rows disagree by more than rounding: the largest violation
/// `inconsistency` of `J q̈ = b` that no q̈ removes is above 1e-7 of max(1, `scale`), the size
/// of the right side it is measured against. Redundant rows meet this on the constraint manifold
/// (their disagreement is rounding there) and not always off it: an integration stage, a state
/// that drifted. A plain evaluation refuses such rows (`Error::InconsistentConstraints`); the
/// predictor's stages and their linearization take the least-squares λ
/// (`DynamicsOptions::stage`), and the prediction counts them
/// (`Trajectory::least_squares_evaluations`).
pub fn disagree_beyond_rounding(inconsistency: f64, scale: f64) -> bool {
    inconsistency > 1e-7 * scale.max(1.0)
}

/// Baumgarte stabilisation gains: `J q̈ = −γ − K_d (J v) − K_p φ`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Baumgarte {
    /// Position gain K_p [1/s²].
    pub kp: f64,
    /// Velocity gain K_d [1/s].
    pub kd: f64,
}

impl Baumgarte {
    /// Critically damped gains for a residual time constant T [s]: K_d = 2/T, K_p = 1/T².
    pub fn from_time_constant(t: f64) -> Self {
        Self {
            kp: 1.0 / (t * t),
            kd: 2.0 / t,
        }
    }
}

/// Which formulation solves the constrained dynamics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Formulation {
    /// Embedded unless constraint forces are asked for.
    #[default]
    Auto,
    /// KKT system through M's Cholesky factor and J M⁻¹ Jᵀ; returns λ.
    Multipliers,
    /// Voronets' multiplier-free form in the independent coordinates; no λ.
    Embedded,
}
