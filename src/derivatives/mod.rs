//! Analytic derivatives of the dynamics: inverse dynamics (∂τ/∂q, ∂τ/∂v), forward dynamics
//! (∂q̈/∂q, ∂q̈/∂v, M⁻¹) and the constrained forward dynamics of the multiplier form
//! (∂q̈/∂(q, v, τ), ∂λ/∂(q, v, τ)), free functions on a reusable [`DerivativeData`].
//!
//! Convention (Pinocchio's, docs/architecture.md): ∂/∂q is the derivative along δ ∈ R^nv in
//! q ⊕ δ (`Model::integrate` with unit time), a right, tangent-space perturbation: nv columns.
//! For a free-flyer, δ[0:3] moves the base origin by R δ[0:3] and δ[3:6] rotates it to
//! R Exp(δ[3:6]) (base axes); a planar base likewise in its own frame. ∂/∂v and ∂/∂τ are plain
//! partials. Matrices are `X[(i, j)] = ∂out_i/∂in_j`.
//!
//! Constrained derivatives differentiate the KKT system
//! `[M Jᵀ; J 0][q̈; −λ] = [τ − h; −(γ + K_d J v + K_p φ)]` with anchors and gains fixed:
//! `[M Jᵀ; J 0][∂q̈; −∂λ] = −[∂(RNEA(q, v, q̈) − Jᵀλ); ∂(J q̈ + γ + K_d J v + K_p φ)]` at fixed
//! (q̈, λ), solved through M⁻¹ and the Schur complement J M⁻¹ Jᵀ. Where J is rank deficient
//! (two wheels on one axle) λ is not unique, so it has no derivative: the λ derivatives are zero
//! and `DerivativeData::lambda_unique` is false. The q̈ derivatives are those of the multiplier
//! solve's least-squares reconciliation of the rows (λ = K⁺ r, K = J M⁻¹ Jᵀ: the right-hand
//! side is projected onto range(K)); along admissible directions (J δv = 0) they are unique.

mod aba;
mod constrained;
mod data;
mod kkt;
mod point;
mod rnea;
mod rolling;
mod rows;
mod weld;

pub use aba::{aba_derivatives, inverse_mass_matrix};
pub use constrained::constrained_dynamics_derivatives;
pub use data::DerivativeData;
pub use rnea::rnea_derivatives;
