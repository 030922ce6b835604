//! What a scene file says about a constraint (serde); `ConstraintSet::new` turns it into the
//! statically dispatched internal kinds.

use serde::Deserialize;

/// One row direction: translations along, or rotations about, an axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Row {
    X,
    Y,
    Z,
    Rx,
    Ry,
    Rz,
}

impl Row {
    /// Index in a `[lin; ang]` 6-vector.
    pub fn index(self) -> usize {
        self as usize
    }
    pub fn name(self) -> &'static str {
        ["x", "y", "z", "rx", "ry", "rz"][self as usize]
    }
}

/// Which axes a weld's rows are expressed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Axes {
    #[default]
    World,
    /// The axes of `frame_b`.
    Local,
}

fn world() -> String {
    "world".into()
}
fn xyz() -> Vec<Row> {
    vec![Row::X, Row::Y, Row::Z]
}
fn all_rows() -> Vec<Row> {
    vec![Row::X, Row::Y, Row::Z, Row::Rx, Row::Ry, Row::Rz]
}
fn up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// A constraint as declared in a scene, `kind:` selecting the variant.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ConstraintSpec {
    /// Point `point_a` of `frame_a` held at point `point_b` of `frame_b` (or the world), selected
    /// world-axis rows. λ: force on frame_a's point [N], world axes.
    Point {
        name: String,
        frame_a: String,
        #[serde(default)]
        point_a: [f64; 3],
        #[serde(default = "world")]
        frame_b: String,
        #[serde(default)]
        point_b: [f64; 3],
        #[serde(default = "xyz")]
        rows: Vec<Row>,
    },
    /// Relative pose of `frame_a` and `frame_b` fixed (selected rows). λ: wrench on frame_a at its
    /// origin [N, N·m] in `axes`.
    Weld {
        name: String,
        frame_a: String,
        #[serde(default = "world")]
        frame_b: String,
        #[serde(default)]
        axes: Axes,
        #[serde(default = "all_rows")]
        rows: Vec<Row>,
        /// Target position of A's origin in B [m] (default: coincident).
        #[serde(default)]
        relative_xyz: [f64; 3],
        /// Target orientation of A in B, roll-pitch-yaw [rad] (default: aligned).
        #[serde(default)]
        relative_rpy: [f64; 3],
    },
    /// `|p_a − p_b| = distance` [m]. λ: force on A's point along n = (p_a − p_b)/|p_a − p_b| [N] (λ > 0 pushes A away from B).
    Distance {
        name: String,
        frame_a: String,
        #[serde(default)]
        point_a: [f64; 3],
        #[serde(default = "world")]
        frame_b: String,
        #[serde(default)]
        point_b: [f64; 3],
        distance: f64,
    },
    /// `a·q_i + b·q_j = c` on two 1-DOF joints. λ: generalized force [N·m or N] per unit of the row.
    Coupling {
        name: String,
        joint_i: String,
        joint_j: String,
        a: f64,
        b: f64,
        c: f64,
    },
    /// Wheel rolling without slipping on a plane: the wheel's material point at the contact has zero
    /// velocity. λ: contact force by the ground on the wheel [N], world axes.
    Rolling {
        name: String,
        wheel: String,
        axis: [f64; 3],
        radius: f64,
        #[serde(default = "up")]
        plane_normal: [f64; 3],
        #[serde(default)]
        plane_height: f64,
    },
    /// Velocity of `frame`'s origin along its own `axis` is zero (knife edge). λ: lateral force [N].
    NoSideSlip {
        name: String,
        frame: String,
        axis: [f64; 3],
    },
}

impl ConstraintSpec {
    pub fn name(&self) -> &str {
        match self {
            ConstraintSpec::Point { name, .. }
            | ConstraintSpec::Weld { name, .. }
            | ConstraintSpec::Distance { name, .. }
            | ConstraintSpec::Coupling { name, .. }
            | ConstraintSpec::Rolling { name, .. }
            | ConstraintSpec::NoSideSlip { name, .. } => name,
        }
    }
}
