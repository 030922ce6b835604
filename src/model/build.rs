//! Building a `Model` from URDF text: validation with errors that name the file and element,
//! merging of fixed (and locked) joints, and the scene's choice of base.

use super::check;
use super::inertial::{link_inertia, validate_inertial};
use super::{Body, Frame, Joint, JointKind, Limits, Mimic, Model};
use crate::error::{Error, Result};
use crate::spatial::{Inertia, SE3, rotation_from_rpy};
use nalgebra::{Matrix3, Vector3};
use serde::Deserialize;
use std::collections::HashMap;

/// How the URDF root link is attached to the world.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BaseType {
    /// Root link welded to the world.
    #[default]
    Fixed,
    /// Root link moves in the world x-y plane: q = [x, y, yaw], v = [vx, vy, ωz] in the base frame.
    Planar,
    /// Free-flyer: q = [x, y, z, qx, qy, qz, qw], v = [v_lin; ω] in the base frame.
    Floating,
}

/// What a scene decides about the model.
#[derive(Clone, Debug)]
pub struct ModelOptions {
    /// How the root link is attached to the world (default fixed).
    pub base: BaseType,
    /// Gravity in world axes [m/s²].
    pub gravity: Vector3<f64>,
    /// Joints held at a position [rad or m]: merged like fixed joints, so they cost nothing.
    pub locked_joints: Vec<(String, f64)>,
    /// What to do with a moving body whose merged inertia is not physical (default: refuse).
    pub inertia: InertiaPolicy,
}

/// `model.inertia:` in a scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InertiaPolicy {
    /// Refuse the model, naming the body, its links and its principal moments.
    #[default]
    Check,
    /// Replace the body's rotational inertia by the nearest physical one (same principal axes;
    /// negative moments to 0, then the largest moved down and the others up by a third of the
    /// triangle-inequality excess each) and report it in `Model::warnings`.
    Repair,
}

impl Default for ModelOptions {
    fn default() -> Self {
        Self {
            base: BaseType::Fixed,
            gravity: Vector3::new(0.0, 0.0, -9.81),
            locked_joints: vec![],
            inertia: InertiaPolicy::Check,
        }
    }
}

impl Model {
    /// Build a model from a URDF file.
    pub fn from_urdf_file(path: impl AsRef<std::path::Path>, opts: &ModelOptions) -> Result<Model> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        Self::from_urdf_str(&text, &path.display().to_string(), opts)
    }

    /// Build a model from URDF text; `file` names the source in errors.
    pub fn from_urdf_str(text: &str, file: &str, opts: &ModelOptions) -> Result<Model> {
        let text = super::urdf_text::prepare(text, file)?;
        let robot = urdf_rs::read_from_string(&text).map_err(|e| Error::Urdf {
            file: file.to_string(),
            element: "robot".to_string(),
            message: e.to_string(),
        })?;
        Builder::new(&robot, file, opts)?.build()
    }
}

fn pose_to_se3(p: &urdf_rs::Pose) -> SE3 {
    SE3::new(rotation_from_rpy(&p.rpy.0), Vector3::from(p.xyz.0))
}

struct Builder<'a> {
    robot: &'a urdf_rs::Robot,
    file: &'a str,
    opts: &'a ModelOptions,
    children: HashMap<&'a str, Vec<usize>>,
    locked: HashMap<&'a str, f64>,
    /// The root link (no parent joint).
    root: &'a str,
    link_index: HashMap<&'a str, usize>,
    /// Per link, why its own rotational inertia is not physical (judged after merging).
    link_defects: Vec<Option<String>>,
    model: Model,
}

impl<'a> Builder<'a> {
    fn new(robot: &'a urdf_rs::Robot, file: &'a str, opts: &'a ModelOptions) -> Result<Self> {
        let err = |element: String, message: String| Error::Urdf {
            file: file.to_string(),
            element,
            message,
        };
        let g = opts.gravity.norm();
        if !g.is_finite() || g > crate::limits::MAX_GRAVITY {
            return Err(Error::Invalid(format!(
                "gravity = [{}, {}, {}] m/s²: |g| must be finite and at most {:e} m/s²",
                opts.gravity.x,
                opts.gravity.y,
                opts.gravity.z,
                crate::limits::MAX_GRAVITY
            )));
        }
        let mut link_names: HashMap<&str, usize> = HashMap::new();
        let mut link_defects = Vec::with_capacity(robot.links.len());
        for (i, l) in robot.links.iter().enumerate() {
            if link_names.insert(l.name.as_str(), i).is_some() {
                return Err(err(
                    format!("link '{}'", l.name),
                    "duplicate link name".into(),
                ));
            }
            link_defects.push(
                validate_inertial(&l.inertial).map_err(|m| err(format!("link '{}'", l.name), m))?,
            );
        }
        let mut children: HashMap<&str, Vec<usize>> = HashMap::new();
        let mut parent_of: HashMap<&str, &str> = HashMap::new();
        for (i, j) in robot.joints.iter().enumerate() {
            let el = format!("joint '{}'", j.name);
            for l in [&j.parent.link, &j.child.link] {
                if !link_names.contains_key(l.as_str()) {
                    return Err(err(el, format!("refers to unknown link '{l}'")));
                }
            }
            if let Some(p) = parent_of.insert(j.child.link.as_str(), j.name.as_str()) {
                return Err(err(
                    el,
                    format!(
                        "link '{}' already has parent joint '{p}': the joint graph is not a tree \
                         (a closed loop must be declared as a constraint in the scene)",
                        j.child.link
                    ),
                ));
            }
            children.entry(j.parent.link.as_str()).or_default().push(i);
        }
        let roots: Vec<&str> = robot
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|n| !parent_of.contains_key(n))
            .collect();
        match roots.len() {
            1 => {}
            0 => {
                return Err(err(
                    "robot".into(),
                    "the joint graph has a cycle: no root link".into(),
                ));
            }
            _ => {
                return Err(err(
                    "robot".into(),
                    format!(
                        "the joint graph has {} root links: {}",
                        roots.len(),
                        roots.join(", ")
                    ),
                ));
            }
        }
        let mut locked = HashMap::new();
        for (name, value) in &opts.locked_joints {
            if !robot.joints.iter().any(|j| &j.name == name) {
                return Err(err(
                    format!("locked joint '{name}'"),
                    "no joint of that name in the URDF".into(),
                ));
            }
            locked.insert(name.as_str(), *value);
        }
        let model = Model {
            name: robot.name.clone(),
            bodies: vec![Body {
                name: "world".into(),
                parent: 0,
                joint: Joint {
                    name: "universe".into(),
                    kind: JointKind::revolute(Vector3::z()),
                    idx_q: 0,
                    idx_v: 0,
                    subspace: [Default::default(); 6],
                },
                placement: SE3::identity(),
                inertia: Inertia::zero(),
                placement_rotates: false,
            }],
            frames: vec![Frame {
                name: "world".into(),
                body: 0,
                placement: SE3::identity(),
            }],
            nq: 0,
            nv: 0,
            q_names: vec![],
            v_names: vec![],
            gravity: opts.gravity,
            limits: Limits::default(),
            mimics: vec![],
            base: opts.base,
            v_parent: vec![],
            v_subtree_end: vec![],
            warnings: vec![],
            singular: None,
        };
        Ok(Self {
            robot,
            file,
            opts,
            children,
            locked,
            root: roots[0],
            link_index: link_names,
            link_defects,
            model,
        })
    }

    fn build(mut self) -> Result<Model> {
        let root = self.root.to_string();
        let root_body = match self.opts.base {
            super::BaseType::Fixed => 0,
            super::BaseType::Planar => self.add_body(
                &root,
                "root_joint",
                JointKind::Planar,
                0,
                SE3::identity(),
                None,
            ),
            super::BaseType::Floating => self.add_body(
                &root,
                "root_joint",
                JointKind::FreeFlyer,
                0,
                SE3::identity(),
                None,
            ),
        };
        self.visit(&root, root_body)?;
        self.check_unreachable()?;
        self.model.v_subtree_end = super::subtree_ends(&self.model.v_parent);
        for j in &self.robot.joints {
            if let Some(m) = &j.mimic {
                self.model.mimics.push(Mimic {
                    joint: j.name.clone(),
                    mimicked: m.joint.clone(),
                    multiplier: m.multiplier.unwrap_or(1.0),
                    offset: m.offset.unwrap_or(0.0),
                });
            }
        }
        check::bodies(
            &mut self.model,
            &self.robot.links,
            &self.link_defects,
            self.opts.inertia,
            self.file,
        )?;
        self.model.singular = check::singular_joint(&self.model, self.file);
        Ok(self.model)
    }

    fn check_unreachable(&self) -> Result<()> {
        let reached: std::collections::HashSet<&str> =
            self.model.frames.iter().map(|f| f.name.as_str()).collect();
        for l in &self.robot.links {
            if !reached.contains(l.name.as_str()) && l.name != self.root {
                return Err(Error::Urdf {
                    file: self.file.to_string(),
                    element: format!("link '{}'", l.name),
                    message: "not reachable from the root link: the joint graph has a cycle".into(),
                });
            }
        }
        Ok(())
    }

    /// Attach `root` and everything below it, depth-first with children in file order (the
    /// numbering of bodies and coordinates). An explicit stack, not recursion: a chain of
    /// thousands of links must not overflow the thread's stack.
    fn visit(&mut self, root: &str, root_body: usize) -> Result<()> {
        enum Item {
            /// A link attached to `body` at `body_m_link`.
            Link(usize, usize, SE3),
            /// A joint below a link of `body`, whose frame sits at `body_m_parent_link`.
            Joint(usize, usize, SE3),
        }
        let mut stack = vec![Item::Link(
            self.link_index[root],
            root_body,
            SE3::identity(),
        )];
        while let Some(item) = stack.pop() {
            match item {
                Item::Link(li, body, body_m_link) => {
                    let l = &self.robot.links[li];
                    if !(body == 0 && l.name == "world") {
                        self.model.frames.push(Frame {
                            name: l.name.clone(),
                            body,
                            placement: body_m_link,
                        });
                    }
                    if body != 0 {
                        let inertia = link_inertia(&l.inertial).transformed(&body_m_link);
                        let b = &mut self.model.bodies[body];
                        b.inertia = b.inertia.add(&inertia);
                    }
                    if let Some(kids) = self.children.get(l.name.as_str()) {
                        for &ji in kids.iter().rev() {
                            stack.push(Item::Joint(ji, body, body_m_link));
                        }
                    }
                }
                Item::Joint(ji, body, body_m_link) => {
                    let j = &self.robot.joints[ji];
                    let body_m_joint = body_m_link.compose(&pose_to_se3(&j.origin));
                    let kind = self.joint_kind(j)?;
                    let child = self.link_index[j.child.link.as_str()];
                    match (kind, self.locked.get(j.name.as_str()).copied()) {
                        (None, _) => stack.push(Item::Link(child, body, body_m_joint)),
                        (Some(kind), Some(value)) => {
                            if kind.nq() != 1 {
                                return Err(self.err_joint(j, "only 1-DOF joints can be locked"));
                            }
                            let at = body_m_joint.compose(&kind.transform(&[value]));
                            stack.push(Item::Link(child, body, at));
                        }
                        (Some(kind), None) => {
                            let link = j.child.link.clone();
                            let nb =
                                self.add_body(&link, &j.name, kind, body, body_m_joint, Some(j));
                            stack.push(Item::Link(child, nb, SE3::identity()));
                        }
                    }
                }
            }
        }
        Ok(())
    }

    fn err_joint(&self, j: &urdf_rs::Joint, message: &str) -> Error {
        Error::Urdf {
            file: self.file.to_string(),
            element: format!("joint '{}'", j.name),
            message: message.to_string(),
        }
    }

    fn joint_kind(&self, j: &urdf_rs::Joint) -> Result<Option<JointKind>> {
        let axis = Vector3::from(j.axis.xyz.0);
        let unit = || {
            let n = axis.norm();
            if !(n > 1e-12 && n.is_finite()) {
                Err(self.err_joint(j, "axis is zero or not finite"))
            } else {
                Ok(axis / n)
            }
        };
        use urdf_rs::JointType as T;
        Ok(match j.joint_type {
            T::Fixed => None,
            T::Revolute | T::Continuous => Some(JointKind::revolute(unit()?)),
            T::Prismatic => Some(JointKind::Prismatic { axis: unit()? }),
            T::Floating => Some(JointKind::FreeFlyer),
            T::Planar => {
                let a = unit()?;
                if (a - Vector3::z()).norm() > 1e-12 {
                    return Err(
                        self.err_joint(j, "planar joints are supported with axis 0 0 1 only")
                    );
                }
                Some(JointKind::Planar)
            }
            T::Spherical => {
                return Err(self.err_joint(j, "joint type 'spherical' is not supported"));
            }
        })
    }

    fn add_body(
        &mut self,
        link: &str,
        joint_name: &str,
        kind: JointKind,
        parent: usize,
        placement: SE3,
        urdf_joint: Option<&urdf_rs::Joint>,
    ) -> usize {
        let m = &mut self.model;
        let (nq, nv) = (kind.nq(), kind.nv());
        let (idx_q, idx_v) = (m.nq, m.nv);
        m.nq += nq;
        m.nv += nv;
        let base_names = |suffixes: &[&str]| -> Vec<String> {
            suffixes
                .iter()
                .map(|s| format!("{joint_name}:{s}"))
                .collect()
        };
        let (qn, vn) = match kind {
            JointKind::FreeFlyer => (
                base_names(&["x", "y", "z", "qx", "qy", "qz", "qw"]),
                base_names(&[
                    "vx_local", "vy_local", "vz_local", "wx_local", "wy_local", "wz_local",
                ]),
            ),
            JointKind::Planar => (
                base_names(&["x", "y", "yaw"]),
                base_names(&["vx_local", "vy_local", "wz"]),
            ),
            _ => (vec![joint_name.to_string()], vec![joint_name.to_string()]),
        };
        m.q_names.extend(qn);
        m.v_names.extend(vn);
        let lim = &mut m.limits;
        let (lo, hi, vel, eff, damp) = match (urdf_joint, &kind) {
            (Some(j), JointKind::Revolute { .. } | JointKind::Prismatic { .. }) => {
                let continuous = j.joint_type == urdf_rs::JointType::Continuous;
                let (lo, hi) = if continuous || j.limit.lower >= j.limit.upper {
                    (f64::NEG_INFINITY, f64::INFINITY)
                } else {
                    (j.limit.lower, j.limit.upper)
                };
                let vel = if j.limit.velocity > 0.0 {
                    j.limit.velocity
                } else {
                    f64::INFINITY
                };
                let eff = if j.limit.effort > 0.0 {
                    j.limit.effort
                } else {
                    f64::INFINITY
                };
                let damp = j.dynamics.as_ref().map(|d| d.damping).unwrap_or(0.0);
                (lo, hi, vel, eff, damp)
            }
            _ => (
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::INFINITY,
                f64::INFINITY,
                0.0,
            ),
        };
        lim.q_lower.extend(std::iter::repeat_n(lo, nq));
        lim.q_upper.extend(std::iter::repeat_n(hi, nq));
        lim.velocity.extend(std::iter::repeat_n(vel, nv));
        lim.effort.extend(std::iter::repeat_n(eff, nv));
        lim.damping.extend(std::iter::repeat_n(damp, nv));
        // Last velocity coordinate of the nearest ancestor body that has one.
        let mut up = if parent == 0 {
            usize::MAX
        } else {
            m.bodies[parent].joint.idx_v + m.bodies[parent].joint.kind.nv() - 1
        };
        for k in 0..nv {
            m.v_parent.push(up);
            up = idx_v + k;
        }
        let subspace = kind.motion_subspace();
        m.bodies.push(Body {
            name: link.to_string(),
            parent,
            joint: Joint {
                name: joint_name.to_string(),
                kind,
                idx_q,
                idx_v,
                subspace,
            },
            placement_rotates: placement.rotation != Matrix3::identity(),
            placement,
            inertia: Inertia::zero(),
        });
        m.bodies.len() - 1
    }
}
