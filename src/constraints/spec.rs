//! What a scene file says about a constraint (serde); `ConstraintSet::new` turns it into the
//! statically dispatched internal kinds.

use serde::Deserialize;
use std::collections::BTreeMap;

/// One row direction: translations along, or rotations about, an axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Row {
    /// Translation along x (`x` in YAML).
    X,
    /// Translation along y (`y` in YAML).
    Y,
    /// Translation along z (`z` in YAML).
    Z,
    /// Rotation about x (`rx` in YAML).
    Rx,
    /// Rotation about y (`ry` in YAML).
    Ry,
    /// Rotation about z (`rz` in YAML).
    Rz,
}

impl Row {
    /// Index in a `[lin; ang]` 6-vector.
    pub fn index(self) -> usize {
        self as usize
    }
    /// The YAML spelling: `x`, `y`, `z`, `rx`, `ry` or `rz`.
    pub fn name(self) -> &'static str {
        ["x", "y", "z", "rx", "ry", "rz"][self as usize]
    }
}

/// Which axes a weld's rows are expressed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Axes {
    /// World axes (`world`, the default).
    #[default]
    World,
    /// The axes of `frame_b`.
    Local,
}

/// Which virtual displacements a `velocity` constraint's force is orthogonal to (seed 001).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VirtualDisplacements {
    /// Chetaev: ∂f/∂v δv = 0, force along ∂f/∂v (`chetaev`, the default).
    #[default]
    Chetaev,
    /// The seed's velocity-determined displacements, eqs. (5)–(6) (`velocity_determined`).
    VelocityDetermined,
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
        /// `name:` unique constraint name (used in row names `name/row` and errors).
        name: String,
        /// `frame_a:` frame (link or fixed-joint frame) carrying point A.
        frame_a: String,
        /// `point_a:` point A in `frame_a` [m] (default: the frame origin).
        #[serde(default)]
        point_a: [f64; 3],
        /// `frame_b:` frame carrying point B (default: `world`).
        #[serde(default = "world")]
        frame_b: String,
        /// `point_b:` point B in `frame_b` [m] (default: the frame origin).
        #[serde(default)]
        point_b: [f64; 3],
        /// `rows:` world axes held, subset of `[x, y, z]` (default: all three).
        #[serde(default = "xyz")]
        rows: Vec<Row>,
        /// `unilateral:` the contact can push but never pull: with exactly one row, its λ (the
        /// force on A along that world axis) must be ≥ 0 (default false: a bilateral hold). Read
        /// by the acceleration envelope; the dynamics holds every row as an equality.
        #[serde(default)]
        unilateral: bool,
        /// `friction:` Coulomb coefficient μ > 0 of a ground contact (`frame_b: world`, rows with
        /// `z` and `x` and/or `y`): ‖λ_xy‖ ≤ μ λ_z, which also keeps λ_z ≥ 0 (default: none,
        /// friction unchecked). Read by the acceleration envelope.
        #[serde(default)]
        friction: Option<f64>,
    },
    /// Relative pose of `frame_a` and `frame_b` fixed (selected rows). λ: wrench on frame_a at its
    /// origin [N, N·m] in `axes`.
    Weld {
        /// `name:` unique constraint name (used in row names `name/row` and errors).
        name: String,
        /// `frame_a:` the welded frame A.
        frame_a: String,
        /// `frame_b:` the frame A is welded to (default: `world`).
        #[serde(default = "world")]
        frame_b: String,
        /// `axes:` `world` or `local` (B's axes) for the rows and λ (default: `world`).
        #[serde(default)]
        axes: Axes,
        /// `rows:` rows held, subset of `[x, y, z, rx, ry, rz]` (default: all six).
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
        /// `name:` unique constraint name (used in row names `name/row` and errors).
        name: String,
        /// `frame_a:` frame carrying point A.
        frame_a: String,
        /// `point_a:` point A in `frame_a` [m] (default: the frame origin).
        #[serde(default)]
        point_a: [f64; 3],
        /// `frame_b:` frame carrying point B (default: `world`).
        #[serde(default = "world")]
        frame_b: String,
        /// `point_b:` point B in `frame_b` [m] (default: the frame origin).
        #[serde(default)]
        point_b: [f64; 3],
        /// `distance:` required distance |p_a − p_b| [m], positive; no default.
        distance: f64,
    },
    /// `a·q_i + b·q_j = c` on two 1-DOF joints. λ: generalized force [N·m or N] per unit of the row.
    Coupling {
        /// `name:` unique constraint name (used in row names `name/row` and errors).
        name: String,
        /// `joint_i:` first 1-DOF (revolute or prismatic) joint, by URDF name.
        joint_i: String,
        /// `joint_j:` second 1-DOF (revolute or prismatic) joint, by URDF name.
        joint_j: String,
        /// `a:` coefficient of q_i (a and b not both zero); no default.
        a: f64,
        /// `b:` coefficient of q_j; no default.
        b: f64,
        /// `c:` right-hand side [rad or m, as the joints' units combine]; no default.
        c: f64,
    },
    /// Wheel rolling without slipping on a plane: the wheel's material point at the contact has zero
    /// velocity. λ: contact force by the ground on the wheel [N], world axes (with `lateral:
    /// tyre`, along the wheel's rolling direction and the normal).
    Rolling {
        /// `name:` unique constraint name (used in row names `name/row` and errors).
        name: String,
        /// `wheel:` wheel frame; its origin is the wheel centre.
        wheel: String,
        /// `axis:` spin axis in the wheel frame (normalized; must not be parallel to the normal).
        axis: [f64; 3],
        /// `radius:` wheel radius [m], positive; no default. The effective rolling radius
        /// goes here (the contact point lies at it).
        radius: f64,
        /// `axle_offset:` the contact point moved along `axis` by this much [m] (default 0):
        /// an effective track. On a diff drive whose wheels both spin about +y, a positive
        /// offset widens the track at the left wheel and narrows it at the right one.
        #[serde(default)]
        axle_offset: f64,
        /// `axle_offset_turn_gain:` k [m/(rad/s)²] (default 0): the offset grows to
        /// `axle_offset` + k ω_n² with the wheel's turn rate ω_n about the plane normal (on
        /// level ground the chassis's yaw rate): a wide tyre's track that widens in fast turns.
        /// Needs drift control (`integration.drift`: projection or baumgarte).
        #[serde(default)]
        axle_offset_turn_gain: f64,
        /// `lateral:` what holds the wheel sideways: `rigid` (default), the contact's own row,
        /// or `tyre`, the wheel's `forces.tyres` entry (the tread creeps and skids sideways
        /// under the force it takes); the contact then keeps only its rolling row.
        #[serde(default)]
        lateral: LateralGrip,
        /// `plane_normal:` ground-plane normal, world axes (normalized; default `[0, 0, 1]`).
        #[serde(default = "up")]
        plane_normal: [f64; 3],
        /// `plane_height:` h in the plane n·x = h [m] (default 0).
        #[serde(default)]
        plane_height: f64,
        /// `friction:` Coulomb coefficient μ > 0: ‖λ_t‖ ≤ μ λ_n (default: none, friction
        /// unchecked). The normal row pushes but never pulls whatever μ. Read by the
        /// acceleration envelope.
        #[serde(default)]
        friction: Option<f64>,
    },
    /// Velocity of `frame`'s origin along its own `axis` is zero (knife edge). λ: lateral force [N].
    NoSideSlip {
        /// `name:` unique constraint name (used in row names `name/row` and errors).
        name: String,
        /// `frame:` frame whose origin must not slide along `axis`.
        frame: String,
        /// `axis:` the blocked direction in `frame`'s axes (normalized); no default.
        axis: [f64; 3],
    },
    /// `f(q, v, t) = 0` written as an expression (`+ - * / ^`, `sqrt sin cos tan exp ln abs`,
    /// `pi`, `t` [s]), nonholonomic, possibly nonlinear in v. λ: multiplier of the force
    /// (∂f/∂v)ᵀλ [N or N·m per velocity coordinate].
    Velocity {
        /// `name:` unique constraint name (used in row names `name/f` and errors).
        name: String,
        /// `expression:` f, in the symbols of `variables` and `t`; no default.
        expression: String,
        /// `variables:` symbol → `q:NAME` or `v:NAME` (a `q_names` / `v_names` entry, e.g.
        /// `v:root_joint:vx_local`, `q:spin`); default none.
        #[serde(default)]
        variables: BTreeMap<String, String>,
        /// `virtual_displacements:` `chetaev` (default) or `velocity_determined`.
        #[serde(default)]
        virtual_displacements: VirtualDisplacements,
        /// `dependent:` the velocity symbol the embedded form solves f for (at most one per
        /// constraint; default: chosen from ∂f/∂v).
        #[serde(default)]
        dependent: Vec<String>,
        /// `reference_velocity:` velocity symbol → v⁽⁰⁾ of the seed's eq. (4), the reference
        /// frame's velocity the velocity-determined B is expanded about (default 0) [m/s or
        /// rad/s]; only with `velocity_determined`.
        #[serde(default)]
        reference_velocity: BTreeMap<String, f64>,
    },
}

impl ConstraintSpec {
    /// The constraint's `name:`.
    pub fn name(&self) -> &str {
        match self {
            ConstraintSpec::Point { name, .. }
            | ConstraintSpec::Weld { name, .. }
            | ConstraintSpec::Distance { name, .. }
            | ConstraintSpec::Coupling { name, .. }
            | ConstraintSpec::Rolling { name, .. }
            | ConstraintSpec::NoSideSlip { name, .. }
            | ConstraintSpec::Velocity { name, .. } => name,
        }
    }
}

/// A rolling contact's `lateral:` key: what holds its wheel sideways.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LateralGrip {
    /// The contact's lateral row: no sideways slip at all.
    #[default]
    Rigid,
    /// The wheel's tyre (`forces.tyres`): sideways creep and skid.
    Tyre,
}
