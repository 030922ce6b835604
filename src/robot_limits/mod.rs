//! A robot's limits in its dynamics: actuators within their effort, contacts that push and never
//! pull, friction cones — what they are called, when one is reached, which cannot be checked,
//! and the rows that state them in a second-order cone program. The acceleration envelope
//! (`envelope/`) and the dynamic projection (`projection/dynamic.rs`) pose their programs with
//! `program.rs`'s builder; the prediction's contact check (`predict/contacts.rs`) names what it
//! cannot check with the same kinds.
//!
//! ```text
//! |τ_k| ≤ e_k            URDF <limit effort> of each actuated joint          effort
//! λ_n ≥ 0                the normal force pushes                             lift_off
//! ‖λ_t‖ ≤ μ λ_n          Coulomb's cone                                      friction
//! lo ≤ v ≤ hi            a coordinate's bound (the dynamic projection's)     bound
//! ```
//!
//! Not to be confused with [`crate::limits`], the accepted ranges of a scene's and a request's
//! numbers.

mod active;
mod actuator;
mod contact;
mod kind;
pub(crate) mod program;

pub use active::{active_limits, max_active_limits};
pub use actuator::Actuator;
pub use contact::unchecked_contact_limits;
pub use kind::{ACTIVE_TOLERANCE, Binding, LimitKind, NamedLimit};
