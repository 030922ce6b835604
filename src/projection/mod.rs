//! Constraint-respecting velocity projection: the velocity closest to a desired one, in the
//! kinetic-energy metric, that every constraint of the scene and every bound allows.
//!
//! ```text
//! v* = argmin_v  ½ (v − v_des)ᵀ M(q) (v − v_des)
//!      subject to  J(q) v = 0     holonomic rows at velocity level, rolling, couplings
//!                  lo ≤ v ≤ hi    URDF velocity limits of 1-DOF joints, request bounds,
//!                                 v_current ± a_max·dt
//!                  A v ≤ b        user inequalities
//! KKT:  M (v* − v_des) = Jᵀλ + ν − Aᵀη,
//!       ν ≥ 0 on active lower bounds, ν ≤ 0 on active upper bounds, η ≥ 0
//! ```
//! Sizes: nv velocity coordinates, nc constraint rows (J is nc × nv), m rows of A. λ are the
//! impulses the constraints apply [N·s or N·m·s per row, the rows' force convention]: `M Δv`
//! is the generalized impulse that turns v_des into v*.
//!
//! - Equality constraints only (no finite bound, no A): one factorization, no QP solver —
//!   `[M Jᵀ; J 0][v; −λ] = [M v_des; 0]` through M's branch-sparse LTL factor and the Schur
//!   complement J M⁻¹ Jᵀ, redundant rows with minimum-norm λ and the rank deficiency reported
//!   (`kkt.rs`). Allocation-free after [`VelocityProjector::new`].
//! - With bounds or inequalities: if the equality-only v* already satisfies them it is optimal;
//!   otherwise a scaled Clarabel QP, built once per structure and updated in place (`qp.rs`),
//!   finds the active set and a KKT re-solve with the active rows held (`polish.rs`) gives v*,
//!   λ, ν to machine precision. An infeasible request returns `Status::Infeasible` with a
//!   minimal named conflicting set (`diagnose.rs`), never a vector.
//!
//! - A planner's twist request (`mode: twist`, the default with `base_twist`) is answered with
//!   planner semantics instead: nearest in the requested components, then one uniform scale
//!   that satisfies every bound (`twist.rs`).
//!
//! - With a control period Δt (`period` in a request): the velocity reachable within Δt under
//!   the robot's efforts, friction cones and contacts, nearest in the same metric — a cone
//!   program (`dynamic.rs`, [`DynamicProjector`]); Δt = 0 is the kinematic projection above.
//!
//! Entry points: [`VelocityProjector::project`] (numeric [`ProjectionProblem`], coordinate
//! order), [`VelocityProjector::project_request`] (named [`ProjectionRequest`] → [`Projection`]),
//! and [`project_system`] for a [`System`]. See `docs/projection.md`.

mod activity;
mod diagnose;
mod dynamic;
mod dynamic_diagnose;
mod dynamic_socp;
mod kkt;
mod polish;
mod problem;
mod projector;
mod qp;
mod report;
mod request;
mod twist;

pub use diagnose::Conflict;
pub use dynamic::DynamicProjector;
pub use dynamic_diagnose::DynamicConflict;
pub use problem::{AccelLimit, BoundSource, ProjectionProblem, Side};
pub use projector::{Outcome, SolvePath, Status, VelocityProjector};
pub use report::{
    ActiveBound, ActiveInequality, ConstraintImpulse, DynamicReport, NamedConflict, Projection,
};
pub use request::{
    AccelLimitRequest, Fill, Mode, PerCoordinate, ProjectionRequest, RowSpec, base_dofs,
    coordinate_index,
};

use crate::error::Result;
use crate::system::System;

/// [`VelocityProjector::project_request`] on a [`System`]'s model, constraints and workspaces.
pub fn project_system(
    projector: &mut VelocityProjector,
    sys: &mut System,
    q: &[f64],
    v_current: &[f64],
    request: &ProjectionRequest,
) -> Result<Projection> {
    let p = sys.parts();
    projector.project_request(
        p.model,
        p.data,
        p.constraints,
        p.rows,
        q,
        v_current,
        request,
    )
}
