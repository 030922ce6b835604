//! The immutable robot `Model`: bodies (URDF links merged across fixed and locked joints), their
//! joints, named frames (every URDF link) and the named generalized coordinates. A payload
//! carried at run time makes a new model ([`Model::with_payload`]).
//!
//! Body 0 is the world ("universe"). Bodies are numbered depth-first over the URDF tree, children in
//! the order their joints appear in the file, so a parent always precedes its children and the
//! coordinates follow the same order (base coordinates first).

mod base;
pub mod base_covariance;
mod build;
mod check;
mod inertial;
mod joint;
mod payload;
mod state_map;
mod urdf_text;

pub use base::{BasePose, BaseTwist, TWIST_TOLERANCE};
pub use build::{BaseType, InertiaPolicy, ModelOptions};
pub use check::{MIN_PIVOT_RATIO, pivot_ratios};
pub use joint::JointKind;
pub use payload::Payload;
pub use state_map::StateMap;
pub use urdf_text::MAX_URDF_MAGNITUDE;

use crate::error::{Error, Result};
use crate::linalg::NO_PARENT;
use crate::spatial::{Inertia, Motion, SE3};
use nalgebra::Vector3;

/// A movable joint between a body and its parent.
#[derive(Clone, Debug)]
pub struct Joint {
    /// URDF joint name (`root_joint` for a planar or floating base).
    pub name: String,
    /// Joint type, with its axis where it has one.
    pub kind: JointKind,
    /// First configuration coordinate.
    pub idx_q: usize,
    /// First velocity coordinate.
    pub idx_v: usize,
    /// Motion subspace columns in the child frame (first `kind.nv()` used).
    pub subspace: [Motion; 6],
}

/// A rigid body: one or more URDF links rigidly attached.
#[derive(Clone, Debug)]
pub struct Body {
    /// Name of the URDF link that carries the joint (the body's own frame).
    pub name: String,
    /// Parent body index (0 = world).
    pub parent: usize,
    /// The joint connecting the body to its parent.
    pub joint: Joint,
    /// `parent_m_joint`: pose of the joint frame in the parent body frame at q = 0.
    pub placement: SE3,
    /// Spatial inertia in the body frame (merged links included).
    pub inertia: Inertia,
    /// Whether `placement` rotates (false: a pure translation, `rpy="0 0 0"`).
    pub placement_rotates: bool,
}

impl Body {
    /// `world_m_body` at q (the whole configuration, nq) for an aligned revolute joint whose
    /// placement does not rotate (most URDF joints: `rpy="0 0 0"`), with `parent_m_body` into
    /// `li`: the parent's rotation turned by the joint (`joint::turned`) instead of composed
    /// with a 3 × 3 product — the same numbers. `None` for every other body (compose
    /// [`JointKind::placed`]). It reads its own angle `q[idx_q]`, so that the kinematics pass
    /// forms the joint's slice of q only on the other path.
    #[inline(always)]
    pub fn placed_in_world(&self, q: &[f64], o_m_parent: &SE3, li: &mut SE3) -> Option<SE3> {
        let JointKind::Revolute {
            aligned: Some((i, sign)),
            ..
        } = &self.joint.kind
        else {
            return None;
        };
        if self.placement_rotates {
            return None;
        }
        let (sn, cs) = joint::sin_cos(q[self.joint.idx_q]);
        let s = sign * sn;
        *li = SE3::new(joint::axis_rotation(*i, s, cs), self.placement.translation);
        let t = o_m_parent.rotation * self.placement.translation + o_m_parent.translation;
        Some(SE3::new(joint::turned(&o_m_parent.rotation, *i, s, cs), t))
    }
}

/// A named frame rigidly attached to a body (every URDF link is one).
#[derive(Clone, Debug)]
pub struct Frame {
    /// Frame name (URDF link name; `world` for frame 0).
    pub name: String,
    /// Body index (0 = world).
    pub body: usize,
    /// `body_m_frame`.
    pub placement: SE3,
}

/// Per-velocity-coordinate limits and damping from the URDF (infinite where the URDF omits them).
#[derive(Clone, Debug, Default)]
pub struct Limits {
    /// Position limits [rad or m], per configuration coordinate.
    pub q_lower: Vec<f64>,
    /// Upper position limits [rad or m], per configuration coordinate.
    pub q_upper: Vec<f64>,
    /// |v| limit [rad/s or m/s], per velocity coordinate.
    pub velocity: Vec<f64>,
    /// |τ| limit [N·m or N], per velocity coordinate.
    pub effort: Vec<f64>,
    /// Viscous damping [N·m·s/rad or N·s/m], per velocity coordinate (URDF `<dynamics damping>`).
    pub damping: Vec<f64>,
}

/// A URDF `<mimic>`: `q_joint = multiplier · q_mimicked + offset`.
#[derive(Clone, Debug, PartialEq)]
pub struct Mimic {
    /// URDF name of the joint carrying the `<mimic>` tag (the follower).
    pub joint: String,
    /// URDF name of the joint it follows (`<mimic joint=...>`).
    pub mimicked: String,
    /// `multiplier` (URDF default 1).
    pub multiplier: f64,
    /// `offset` [rad or m] (URDF default 0).
    pub offset: f64,
}

/// The robot model. Built once, never modified by an algorithm.
#[derive(Clone, Debug)]
pub struct Model {
    /// URDF robot name.
    pub name: String,
    /// Bodies; index 0 is the world and carries no joint worth reading.
    pub bodies: Vec<Body>,
    /// Named frames; index 0 is `world`.
    pub frames: Vec<Frame>,
    /// Number of configuration coordinates (length of q).
    pub nq: usize,
    /// Number of velocity coordinates (length of v, q̈, τ).
    pub nv: usize,
    /// Configuration coordinate names: joint name, or `root_joint:x` etc. for the base.
    pub q_names: Vec<String>,
    /// Velocity coordinate names: joint name, or `root_joint:vx_local` etc. for the base.
    pub v_names: Vec<String>,
    /// Gravity in the world frame [m/s²].
    pub gravity: Vector3<f64>,
    /// URDF limits and damping per coordinate.
    pub limits: Limits,
    /// URDF `<mimic>` tags (each becomes a coupling constraint).
    pub mimics: Vec<Mimic>,
    /// How the root link is attached to the world.
    pub base: BaseType,
    /// Per velocity coordinate, the previous coordinate on the path to the root
    /// (`usize::MAX` for none): the sparsity pattern of M's LTL factor.
    pub v_parent: Vec<usize>,
    /// Per velocity coordinate c, the end (exclusive) of the coordinates that c moves: c and its
    /// descendants are c..v_subtree_end[c] (coordinates are numbered depth-first).
    pub v_subtree_end: Vec<usize>,
    /// What the loader accepted but a user should know, one sentence each naming the file and
    /// link (e.g. a non-physical inertia on a link welded to a sound body, which is ignored).
    pub warnings: Vec<String>,
    /// A joint whose motion moves no inertia, or none independent of the others, at the neutral
    /// and at a generic configuration (M singular). Not an error for the model alone: a
    /// constraint can give that joint its dynamics (a massless rod pinned by a loop closure);
    /// `System::from_scene` refuses the scene when none does.
    pub singular: Option<SingularJoint>,
}

/// Why M is singular: the joint at fault and what it moves.
#[derive(Clone, Debug)]
pub struct SingularJoint {
    /// The URDF source.
    pub file: String,
    /// The joint's name.
    pub joint: String,
    /// Its effective inertia and the links it moves.
    pub message: String,
}

impl SingularJoint {
    /// The load error for a scene in which no constraint fixes this joint.
    pub fn error(&self) -> Error {
        Error::SingularModel {
            file: self.file.clone(),
            joint: format!("joint '{}'", self.joint),
            message: self.message.clone(),
        }
    }
}

impl Model {
    /// Number of bodies including the world.
    pub fn nbodies(&self) -> usize {
        self.bodies.len()
    }

    /// Total mass [kg].
    pub fn total_mass(&self) -> f64 {
        self.bodies.iter().skip(1).map(|b| b.inertia.mass).sum()
    }

    /// Frame index by name (`world` is frame 0).
    pub fn frame_id(&self, name: &str) -> Result<usize> {
        self.frames
            .iter()
            .position(|f| f.name == name)
            .ok_or_else(|| Error::UnknownFrame {
                name: name.to_string(),
                known: self
                    .frames
                    .iter()
                    .map(|f| f.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// Body index of a movable joint by name.
    pub fn joint_body(&self, name: &str) -> Result<usize> {
        self.bodies
            .iter()
            .skip(1)
            .position(|b| b.joint.name == name)
            .map(|i| i + 1)
            .ok_or_else(|| Error::UnknownJoint {
                name: name.to_string(),
                known: self.joint_names().join(", "),
            })
    }

    /// Names of the movable joints in coordinate order.
    pub fn joint_names(&self) -> Vec<&str> {
        self.bodies
            .iter()
            .skip(1)
            .map(|b| b.joint.name.as_str())
            .collect()
    }

    /// Neutral configuration.
    pub fn neutral(&self) -> Vec<f64> {
        let mut q = vec![0.0; self.nq];
        for b in self.bodies.iter().skip(1) {
            let j = &b.joint;
            j.kind.neutral(&mut q[j.idx_q..j.idx_q + j.kind.nq()]);
        }
        q
    }

    /// `q_out = q ⊕ v·dt`, joint by joint on each joint's Lie group.
    pub fn integrate(&self, q: &[f64], v: &[f64], dt: f64, q_out: &mut [f64]) {
        for b in self.bodies.iter().skip(1) {
            let j = &b.joint;
            let (iq, iv) = (j.idx_q, j.idx_v);
            // A 1-DOF joint's group is the line: written here, without the per-joint call and
            // slices (the stages of every step pass each joint).
            if let JointKind::Revolute { .. } | JointKind::Prismatic { .. } = j.kind {
                q_out[iq] = q[iq] + v[iv] * dt;
                continue;
            }
            let (nq, nv) = (j.kind.nq(), j.kind.nv());
            j.kind.integrate(
                &q[iq..iq + nq],
                &v[iv..iv + nv],
                dt,
                &mut q_out[iq..iq + nq],
            );
        }
    }

    /// `v_out = q1 ⊖ q0`.
    pub fn difference(&self, q0: &[f64], q1: &[f64], v_out: &mut [f64]) {
        for b in self.bodies.iter().skip(1) {
            let j = &b.joint;
            let (iq, iv, nq, nv) = (j.idx_q, j.idx_v, j.kind.nq(), j.kind.nv());
            j.kind
                .difference(&q0[iq..iq + nq], &q1[iq..iq + nq], &mut v_out[iv..iv + nv]);
        }
    }

    /// `q̇ = G(q) v`.
    pub fn qdot(&self, q: &[f64], v: &[f64], qdot: &mut [f64]) {
        for b in self.bodies.iter().skip(1) {
            let j = &b.joint;
            let (iq, iv, nq, nv) = (j.idx_q, j.idx_v, j.kind.nq(), j.kind.nv());
            j.kind
                .qdot(&q[iq..iq + nq], &v[iv..iv + nv], &mut qdot[iq..iq + nq]);
        }
    }

    /// Renormalise every quaternion in `q`.
    pub fn normalize(&self, q: &mut [f64]) {
        for b in self.bodies.iter().skip(1) {
            let j = &b.joint;
            j.kind.normalize(&mut q[j.idx_q..j.idx_q + j.kind.nq()]);
        }
    }

    /// Check sizes and finiteness of a state, naming what is wrong.
    pub fn check_state(&self, q: &[f64], v: &[f64]) -> Result<()> {
        crate::error::check_len("q", q, self.nq)?;
        crate::error::check_len("v", v, self.nv)?;
        crate::error::check_finite("q", q)?;
        crate::error::check_finite("v", v)
    }

    /// Index of a configuration coordinate by name.
    pub fn q_index(&self, name: &str) -> Result<usize> {
        self.q_names.iter().position(|n| n == name).ok_or_else(|| {
            Error::Invalid(format!(
                "unknown configuration coordinate '{name}' (known: {})",
                self.q_names.join(", ")
            ))
        })
    }

    /// Index of a velocity coordinate by name.
    pub fn v_index(&self, name: &str) -> Result<usize> {
        self.v_names.iter().position(|n| n == name).ok_or_else(|| {
            Error::Invalid(format!(
                "unknown velocity coordinate '{name}' (known: {})",
                self.v_names.join(", ")
            ))
        })
    }
}

/// [`Model::v_subtree_end`] from the parents: a coordinate's range ends past its last
/// descendant. Depth-first numbering makes every subtree one contiguous range (checked).
pub(crate) fn subtree_ends(v_parent: &[usize]) -> Vec<usize> {
    let mut end: Vec<usize> = (1..=v_parent.len()).collect();
    for c in (0..v_parent.len()).rev() {
        let p = v_parent[c];
        if p != NO_PARENT {
            end[p] = end[p].max(end[c]);
        }
    }
    // Preorder: walking the coordinates in order, each one's parent is the innermost range
    // still open.
    let mut open: Vec<usize> = Vec::new();
    for (d, &p) in v_parent.iter().enumerate() {
        while open.last().is_some_and(|&a| end[a] <= d) {
            open.pop();
        }
        debug_assert_eq!(
            open.last().copied().unwrap_or(NO_PARENT),
            p,
            "coordinate {d}"
        );
        open.push(d);
    }
    end
}
