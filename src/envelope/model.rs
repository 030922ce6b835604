//! What the envelope knows of a robot, built once from the model, the constraint set and the
//! scene's `passive_joints:`: the contacts and their limits, the actuators and their efforts, the
//! coordinates held at zero acceleration and the two base directions.

use crate::constraints::{Constraint, ConstraintSet, Contact, ContactLimits};
use crate::error::{Error, Result};
use crate::linalg::NO_PARENT;
use crate::model::{BaseType, Model};
use crate::robot_limits::program::Structure;
use crate::robot_limits::{Actuator, Binding, LimitKind, unchecked_contact_limits};

/// The envelope's view of a robot (the "model" half of the Model / Data pair; never modified by
/// an evaluation).
#[derive(Clone, Debug)]
pub struct EnvelopeModel {
    /// Velocity coordinates (nv).
    pub nv: usize,
    /// Constraint rows (nc).
    pub nc: usize,
    /// Contacts whose forces are limited, in the constraint set's order.
    pub contacts: Vec<Contact>,
    /// Actuated coordinates in coordinate order: every joint coordinate but the base's and the
    /// `passive_joints:`.
    pub actuators: Vec<Actuator>,
    /// Coordinates held at zero acceleration: the joints that do not drive the base (every
    /// joint that is not on the path from the base to a rolling wheel, e.g. an arm).
    pub held: Vec<usize>,
    /// The base's forward coordinate (`vx_local`): its acceleration is d/dt of the base
    /// twist's forward component [m/s²].
    pub forward: usize,
    /// The base's yaw coordinate (`wz_local` or the planar `yaw` rate) [rad/s²].
    pub yaw: usize,
    /// Limits the envelope cannot check, by kind and name: friction of a contact without μ,
    /// lift-off of a wheel without a normal row (planar base), effort of a joint without one.
    pub unchecked: Vec<(LimitKind, String)>,
    /// Force scale of the activity tests: the weight m·|g| [N] (1 N without gravity).
    pub force_scale: f64,
    /// M's structural pattern, nv × nv row-major: coordinate i couples to c only if one moves
    /// the other (an ancestor in the tree).
    pub(crate) mass_pattern: Vec<bool>,
    /// J's structural pattern, nc × nv row-major: a rolling or point row reads only the
    /// coordinates that move its frames; every other kind's row may read any coordinate.
    pub(crate) jacobian_pattern: Vec<bool>,
}

/// The coordinates that move `body` (its joint's and every ancestor's), as a mask over nv.
fn support(model: &Model, body: usize, mask: &mut [bool]) {
    if body == 0 {
        return;
    }
    let j = &model.bodies[body].joint;
    let mut c = j.idx_v + j.kind.nv() - 1;
    while c != NO_PARENT {
        mask[c] = true;
        c = model.v_parent[c];
    }
}

/// [`EnvelopeModel::mass_pattern`] and [`EnvelopeModel::jacobian_pattern`].
fn patterns(model: &Model, set: &ConstraintSet) -> (Vec<bool>, Vec<bool>) {
    let nv = model.nv;
    let mut mass = vec![false; nv * nv];
    for c in 0..nv {
        let mut a = c;
        while a != NO_PARENT {
            mass[a * nv + c] = true;
            mass[c * nv + a] = true;
            a = model.v_parent[a];
        }
    }
    let mut jac = vec![false; set.nrows * nv];
    let mut mask = vec![false; nv];
    for (k, c) in set.items.iter().enumerate() {
        mask.fill(false);
        match c {
            Constraint::Rolling(rc) => support(model, model.frames[rc.wheel].body, &mut mask),
            Constraint::Point(pc) => {
                support(model, model.frames[pc.frame_a].body, &mut mask);
                support(model, model.frames[pc.frame_b].body, &mut mask);
            }
            _ => mask.fill(true),
        }
        for r in set.ranges[k].clone() {
            jac[r * nv..(r + 1) * nv].copy_from_slice(&mask);
        }
    }
    (mass, jac)
}

impl EnvelopeModel {
    /// Contacts, actuators and held coordinates of `model` under `set`; `passive_joints` are the
    /// scene's joints without actuator. A fixed base has no envelope (an error).
    pub fn new(model: &Model, set: &ConstraintSet, passive_joints: &[String]) -> Result<Self> {
        let (forward, yaw) = match model.base {
            BaseType::Planar => (0, 2),
            BaseType::Floating => (0, 5),
            BaseType::Fixed => {
                return Err(Error::Unsupported {
                    what: "the acceleration envelope of a fixed-base robot".into(),
                    why: "the envelope limits the base's forward and yaw accelerations; give the \
                          scene `base: planar` or `base: floating`"
                        .into(),
                });
            }
        };
        // Body 1 carries the base's joint (planar or floating, parent the world).
        let base_body = 1;
        let nb_base = model.bodies[base_body].joint.kind.nv();
        let mut drives = vec![false; model.nv];
        let mut contacts = vec![];
        let mut unchecked = vec![];
        for (k, contact) in Contact::all(set) {
            if let Constraint::Rolling(rc) = &set.items[k] {
                let mut b = model.frames[rc.wheel].body;
                while b != 0 && b != base_body {
                    let j = &model.bodies[b].joint;
                    drives[j.idx_v..j.idx_v + j.kind.nv()].fill(true);
                    b = model.bodies[b].parent;
                }
            }
            // The envelope assumes nothing a contact does not declare.
            for limit in unchecked_contact_limits(&contact, &ContactLimits::default()) {
                unchecked.push((limit, contact.name.clone()));
            }
            contacts.push(contact);
        }
        let mut actuators = vec![];
        let mut held = vec![];
        for b in model.bodies.iter().skip(base_body + 1) {
            let j = &b.joint;
            let passive = passive_joints.contains(&j.name);
            for c in j.idx_v..j.idx_v + j.kind.nv() {
                if !drives[c] {
                    held.push(c);
                }
                if passive {
                    continue;
                }
                let effort = model.limits.effort[c];
                let listed = (LimitKind::Effort, j.name.clone());
                if !effort.is_finite() && !unchecked.contains(&listed) {
                    unchecked.push(listed);
                }
                actuators.push(Actuator {
                    joint: j.name.clone(),
                    coordinate: c,
                    effort,
                });
            }
        }
        debug_assert!(held.iter().all(|&c| c >= nb_base));
        let weight = model.total_mass() * model.gravity.norm();
        let (mass_pattern, jacobian_pattern) = patterns(model, set);
        Ok(Self {
            nv: model.nv,
            nc: set.nrows,
            contacts,
            actuators,
            held,
            forward,
            yaw,
            unchecked,
            force_scale: if weight > 0.0 { weight } else { 1.0 },
            mass_pattern,
            jacobian_pattern,
        })
    }

    /// The same model with `mu` [-] as the friction coefficient of every contact that declares
    /// none and has a normal row (the ROS nodes' `slip.friction_coefficient`): its friction is
    /// then checked, no longer listed in `unchecked`. A wheel of a planar base has no normal row
    /// and stays unchecked. The CLI assumes nothing.
    pub fn assume_friction(mut self, mu: f64) -> Self {
        for c in &mut self.contacts {
            if c.friction.is_none() && c.normal.is_some() {
                c.friction = Some(mu);
                let name = &c.name;
                self.unchecked
                    .retain(|(kind, n)| !(*kind == LimitKind::Friction && n == name));
            }
        }
        self
    }

    /// What the cone programs on this model are posed on.
    pub(crate) fn structure(&self) -> Structure<'_> {
        Structure {
            nv: self.nv,
            nc: self.nc,
            actuators: &self.actuators,
            contacts: &self.contacts,
            mass_pattern: &self.mass_pattern,
            jacobian_pattern: &self.jacobian_pattern,
        }
    }

    /// Number of actuated coordinates (na).
    pub fn na(&self) -> usize {
        self.actuators.len()
    }

    /// The name a binding limit carries: the joint (effort), the contact (friction, lift-off)
    /// or the coordinate (bound, by index into the model's `v_names`).
    pub fn binding_name<'a>(&'a self, model: &'a Model, b: &Binding) -> &'a str {
        match b.kind {
            LimitKind::Effort => &self.actuators[b.index].joint,
            LimitKind::Friction | LimitKind::LiftOff => &self.contacts[b.index].name,
            LimitKind::Bound => &model.v_names[b.index],
        }
    }
}
