//! The error estimate and its bound by kind of coordinate, each in its own unit: the base's
//! position [m] and orientation [rad] (the tangent entries of a planar or free-flyer joint), and
//! the joints' angles [rad] (revolute, continuous included: a wheel's angle is a joint angle) and
//! displacements [m] (prismatic). One number over all of them would mix a wheel angle (1/r times
//! the base's travel) with the base's metres.

use crate::model::{JointKind, Model};
use serde::Serialize;

/// One value per kind of configuration coordinate (module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ByKind {
    /// Base position [m].
    pub base_m: f64,
    /// Base orientation [rad].
    pub base_rad: f64,
    /// Revolute joint angles [rad].
    pub joint_rad: f64,
    /// Prismatic joint displacements [m].
    pub joint_m: f64,
}

/// The kinds' names, as in [`ByKind`]'s fields and the settings' `max_error_<name>` keys.
pub const KIND_NAMES: [&str; 4] = ["base_m", "base_rad", "joint_rad", "joint_m"];

/// The settings that bound each kind when given (`integration.max_error_<name>`).
pub const KIND_KEYS: [&str; 4] = [
    "integration.max_error_base_m",
    "integration.max_error_base_rad",
    "integration.max_error_joint_rad",
    "integration.max_error_joint_m",
];

impl ByKind {
    /// The same value for every kind.
    pub fn uniform(x: f64) -> Self {
        Self::from_array([x; 4])
    }

    /// The values in the order of [`KIND_NAMES`].
    pub fn to_array(self) -> [f64; 4] {
        [self.base_m, self.base_rad, self.joint_rad, self.joint_m]
    }

    fn from_array([base_m, base_rad, joint_rad, joint_m]: [f64; 4]) -> Self {
        Self {
            base_m,
            base_rad,
            joint_rad,
            joint_m,
        }
    }

    /// The largest value over the kinds (the estimate of every coordinate at once).
    pub fn largest(&self) -> f64 {
        self.to_array().into_iter().fold(0.0, f64::max)
    }

    /// `factor` × the largest |entry| of each kind of the tangent vector `d` (nv) of `model`.
    pub fn of_tangent(model: &Model, d: &[f64], factor: f64) -> Self {
        let mut w = [0.0f64; 4];
        for b in model.bodies.iter().skip(1) {
            let j = &b.joint;
            let at = |k: usize| d[j.idx_v + k].abs();
            match j.kind {
                JointKind::Revolute { .. } => w[2] = w[2].max(at(0)),
                JointKind::Prismatic { .. } => w[3] = w[3].max(at(0)),
                // Tangent [vx, vy, ωz] and [v_lin; ω], both in the child frame.
                JointKind::Planar => {
                    w[0] = w[0].max(at(0)).max(at(1));
                    w[1] = w[1].max(at(2));
                }
                JointKind::FreeFlyer => {
                    (0..3).for_each(|k| w[0] = w[0].max(at(k)));
                    (3..6).for_each(|k| w[1] = w[1].max(at(k)));
                }
            }
        }
        Self::from_array(w.map(|x| factor * x))
    }

    /// The first kind over its bound in `bounds`, as (index in [`KIND_NAMES`], value, bound); a
    /// NaN value counts as over.
    pub fn first_over(&self, bounds: &ByKind) -> Option<(usize, f64, f64)> {
        let (e, b) = (self.to_array(), bounds.to_array());
        (0..4)
            .find(|&k| e[k] > b[k] || e[k].is_nan())
            .map(|k| (k, e[k], b[k]))
    }

    /// max over the kinds of value / bound (0 where the bound is infinite): how far the
    /// estimate is from meeting every bound.
    pub fn excess(&self, bounds: &ByKind) -> f64 {
        let (e, b) = (self.to_array(), bounds.to_array());
        (0..4)
            .map(|k| if b[k].is_finite() { e[k] / b[k] } else { 0.0 })
            .fold(0.0, f64::max)
    }
}
