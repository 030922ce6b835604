//! Constraints: holonomic (point, weld, distance, coupling) and nonholonomic (rolling,
//! no-side-slip), each kind in one file with its residual φ(q), Jacobian rows J and bias γ = J̇v.

mod spec;

pub use spec::{Axes, ConstraintSpec, Row};
