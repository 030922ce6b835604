//! The names of a robot's limits: the kind of each, a limit at its bound, a limit named for
//! output, and the slack below which a limit counts as reached.

use serde::Serialize;

/// Relative slack below which a limit counts as active (the cone programs are solved to
/// 1e-10): of the effort for an actuator, of the force scale (the weight m·|g|) for a contact.
pub const ACTIVE_TOLERANCE: f64 = 1e-6;

/// What kind of limit: one that binds an optimum, or one that cannot be checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LimitKind {
    /// An actuator at its effort (named by its joint).
    Effort,
    /// A contact at its friction cone (named by its constraint).
    Friction,
    /// A contact whose normal force vanishes: it would have to pull (named by its constraint).
    LiftOff,
    /// A coordinate at a bound (named by its coordinate); the envelope bounds no coordinate,
    /// so it never reports one.
    Bound,
}

impl LimitKind {
    /// The kind's name in the JSON: `effort`, `friction`, `lift_off` or `bound`.
    pub const fn name(self) -> &'static str {
        match self {
            LimitKind::Effort => "effort",
            LimitKind::Friction => "friction",
            LimitKind::LiftOff => "lift_off",
            LimitKind::Bound => "bound",
        }
    }
}

/// One binding limit: its kind and the index of what it names (an actuator, a contact, a
/// coordinate, in the order of the program's actuators and contacts or the model's
/// coordinates).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Binding {
    /// What kind of limit.
    pub kind: LimitKind,
    /// Index of the actuator, contact or coordinate.
    pub index: usize,
}

/// A limit named: `{"kind": "effort", "name": "left_wheel_joint"}`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct NamedLimit {
    /// `effort`, `friction`, `lift_off` or `bound`.
    pub kind: &'static str,
    /// The joint, contact or coordinate.
    pub name: String,
}
