//! An actuated coordinate and its effort limit.

/// An actuated velocity coordinate: τ on it is free within ±effort.
#[derive(Clone, Debug, PartialEq)]
pub struct Actuator {
    /// The joint's name.
    pub joint: String,
    /// Its velocity coordinate.
    pub coordinate: usize,
    /// URDF `<limit effort>` [N·m or N]; ∞ where the URDF gives none (unbounded, reported
    /// under `unchecked`).
    pub effort: f64,
}
