//! The kinds of constraint, as one closed enum from the scene file to the wire.

use serde::Serialize;
use std::fmt;

/// A constraint's kind. Its [`name`](ConstraintKind::name) is the word the scene file uses
/// (`kind: rolling`) and the one the CLI's JSON and the ROS messages carry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ConstraintKind {
    /// A point of one frame held at a point of another (or of the world), on chosen axes.
    Point,
    /// A frame held in a pose relative to another (up to 6 rows).
    Weld,
    /// The distance between two points held constant.
    Distance,
    /// A linear coupling of two coordinates (gears, URDF mimic).
    Coupling,
    /// A wheel rolling without slipping on the ground plane (nonholonomic).
    Rolling,
    /// A frame that cannot move along one of its axes (knife edge, nonholonomic).
    NoSideSlip,
    /// f(q, v, t) = 0 written as an expression, possibly nonlinear in v (nonholonomic).
    Velocity,
}

impl ConstraintKind {
    /// The kind's name in scene files, JSON and ROS messages.
    pub const fn name(self) -> &'static str {
        match self {
            ConstraintKind::Point => "point",
            ConstraintKind::Weld => "weld",
            ConstraintKind::Distance => "distance",
            ConstraintKind::Coupling => "coupling",
            ConstraintKind::Rolling => "rolling",
            ConstraintKind::NoSideSlip => "no_side_slip",
            ConstraintKind::Velocity => "velocity",
        }
    }

    /// True for kinds that constrain velocities only (no position residual).
    pub const fn is_nonholonomic(self) -> bool {
        matches!(
            self,
            ConstraintKind::Rolling | ConstraintKind::NoSideSlip | ConstraintKind::Velocity
        )
    }
}

impl fmt::Display for ConstraintKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::ConstraintKind;

    #[test]
    fn wire_names_are_the_scene_names() {
        // The JSON (serde) name, Display and name() are one word, as in `kind:` of a scene.
        for (k, s) in [
            (ConstraintKind::Point, "point"),
            (ConstraintKind::Weld, "weld"),
            (ConstraintKind::Distance, "distance"),
            (ConstraintKind::Coupling, "coupling"),
            (ConstraintKind::Rolling, "rolling"),
            (ConstraintKind::NoSideSlip, "no_side_slip"),
            (ConstraintKind::Velocity, "velocity"),
        ] {
            assert_eq!(k.name(), s);
            assert_eq!(k.to_string(), s);
            assert_eq!(serde_json::to_value(k).unwrap(), serde_json::json!(s));
        }
    }

    #[test]
    fn velocity_level_kinds_are_the_nonholonomic_ones() {
        // The module's definition (constraints/mod.rs): point, weld, distance and coupling are
        // holonomic; rolling, no-side-slip and velocity constrain velocities only.
        for (k, nonholonomic) in [
            (ConstraintKind::Point, false),
            (ConstraintKind::Weld, false),
            (ConstraintKind::Distance, false),
            (ConstraintKind::Coupling, false),
            (ConstraintKind::Rolling, true),
            (ConstraintKind::NoSideSlip, true),
            (ConstraintKind::Velocity, true),
        ] {
            assert_eq!(k.is_nonholonomic(), nonholonomic, "{k}");
        }
    }
}
