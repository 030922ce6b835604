//! Force elements a scene adds to the dynamics (the generalized force Q(t, q, v) that joins τ):
//! joint spring-dampers (and URDF `<dynamics damping>`), point-to-point spring-dampers between
//! frames, joint torques (constant or piecewise-linear in time), frame forces (world axes) and
//! the turning resistance of wide tyres (`turning.rs`) and tyres that grip by friction in place
//! of a rolling constraint (`tyre.rs`).

mod profile;
mod turning;
mod tyre;

pub use profile::piecewise_linear;

use turning::TurningResistance;
pub use turning::TurningResistanceSpec;
use tyre::Tyre;
pub use tyre::TyreSpec;

use crate::algorithm::{
    Data, ReferenceFrame, frame_jacobian, point_jacobian, point_jacobian_transpose_add,
    point_position, point_velocity,
};
use crate::error::{Error, Result};
use crate::model::Model;
use nalgebra::{DMatrix, Vector3};
use serde::Deserialize;

/// `forces:` in a scene.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForcesSpec {
    /// Apply the URDF `<dynamics damping>` of every joint as viscous damping.
    #[serde(default)]
    pub urdf_damping: bool,
    /// `joint_springs:` spring-dampers on 1-DOF joints (default none).
    #[serde(default)]
    pub joint_springs: Vec<JointSpringSpec>,
    /// `springs:` point-to-point spring-dampers between frames (default none).
    #[serde(default)]
    pub springs: Vec<SpringSpec>,
    /// `joint_torques:` constant or time-profiled joint torques (default none).
    #[serde(default)]
    pub joint_torques: Vec<JointTorqueSpec>,
    /// `frame_forces:` constant world-axes forces and torques on frames (default none).
    #[serde(default)]
    pub frame_forces: Vec<FrameForceSpec>,
    /// `turning_resistance:` a wide tyre's scrub about its contact normal, per wheel (default
    /// none).
    #[serde(default)]
    pub turning_resistance: Vec<TurningResistanceSpec>,
    /// `tyres:` wheels that grip the ground by friction, creeping and skidding, in place of a
    /// rolling constraint (default none).
    #[serde(default)]
    pub tyres: Vec<TyreSpec>,
}

/// τ = −k (q − rest) − d q̇ on a 1-DOF joint.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpringSpec {
    /// `joint:` URDF name of a 1-DOF (revolute or prismatic) joint; required.
    pub joint: String,
    /// k [N·m/rad or N/m].
    #[serde(default)]
    pub stiffness: f64,
    /// d [N·m·s/rad or N·s/m].
    #[serde(default)]
    pub damping: f64,
    /// Rest position [rad or m].
    #[serde(default)]
    pub rest: f64,
}

/// Linear spring-damper between two frame points: tension k (L − L₀) + c L̇ [N].
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    /// `name:` spring name, used in error messages; required.
    pub name: String,
    /// `frame_a:` frame carrying end A; required.
    pub frame_a: String,
    /// `point_a:` end A in `frame_a` [m] (default: the frame origin).
    #[serde(default)]
    pub point_a: [f64; 3],
    /// `frame_b:` frame carrying end B (may be `world`); required.
    pub frame_b: String,
    /// `point_b:` end B in `frame_b` [m] (default: the frame origin).
    #[serde(default)]
    pub point_b: [f64; 3],
    /// k [N/m].
    pub stiffness: f64,
    /// c [N·s/m].
    #[serde(default)]
    pub damping: f64,
    /// L₀ [m].
    #[serde(default)]
    pub rest_length: f64,
}

/// A joint torque [N·m or N]: `value`, or a piecewise-linear `profile` of (t [s], τ) pairs
/// (held constant outside its time range).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointTorqueSpec {
    /// `joint:` URDF name of a 1-DOF (revolute or prismatic) joint; required.
    pub joint: String,
    /// `value:` constant torque [N·m or N] (default 0); ignored when `profile` is given.
    #[serde(default)]
    pub value: f64,
    /// `profile:` `[t [s], τ]` pairs with increasing t, linearly interpolated (default none).
    #[serde(default)]
    pub profile: Vec<[f64; 2]>,
}

/// A constant force [N] and torque [N·m] in world axes on a frame point.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameForceSpec {
    /// `frame:` frame the force acts on; required.
    pub frame: String,
    /// `point:` point of application in `frame` [m] (default: the frame origin).
    #[serde(default)]
    pub point: [f64; 3],
    /// `force:` force [N], world axes (default 0).
    #[serde(default)]
    pub force: [f64; 3],
    /// `torque:` torque [N·m], world axes (default 0).
    #[serde(default)]
    pub torque: [f64; 3],
}

/// Frame index, point in the frame [m], force [N] and torque [N·m] in world axes.
#[derive(Clone, Debug)]
struct FrameForce {
    frame: usize,
    point: Vector3<f64>,
    force: Vector3<f64>,
    torque: Vector3<f64>,
}

#[derive(Clone, Debug)]
struct Spring {
    a: (usize, Vector3<f64>),
    b: (usize, Vector3<f64>),
    k: f64,
    c: f64,
    rest: f64,
}

/// The validated force elements of a scene.
#[derive(Clone, Debug, Default)]
pub struct ForceElements {
    /// (q index, v index, k, d, rest) per joint spring-damper (URDF damping folded in).
    joint_springs: Vec<(usize, usize, f64, f64, f64)>,
    springs: Vec<Spring>,
    /// (v index, profile) per joint torque; a constant is a one-point profile.
    torques: Vec<(usize, Vec<[f64; 2]>)>,
    frame_forces: Vec<FrameForce>,
    turning: Vec<TurningResistance>,
    tyres: Vec<Tyre>,
    j3: DMatrix<f64>,
    j6: DMatrix<f64>,
}

fn finite(what: &str, xs: &[f64]) -> Result<()> {
    crate::error::check_finite(what, xs)
}

impl ForceElements {
    /// Whether a wheel tyre (a `forces.tyres` entry with an axis) acts on frame `frame`.
    pub fn has_wheel_tyre(&self, frame: usize) -> bool {
        self.tyres.iter().any(|t| t.is_wheel_on(frame))
    }

    /// The friction [N] the wheel tyre on frame `frame` passes to the ground (kinematics of
    /// `data` at (q, v)); 0 without one.
    pub fn wheel_tyre_friction(&self, model: &Model, data: &Data, frame: usize) -> f64 {
        (self.tyres.iter())
            .find(|t| t.is_wheel_on(frame))
            .map_or(0.0, |t| t.friction_force(model, data))
    }

    /// Validate `forces:` against the model (joints 1-DOF, frames known, values finite, ≥ 0).
    pub fn new(model: &Model, spec: &ForcesSpec) -> Result<Self> {
        let mut fe = ForceElements {
            j3: DMatrix::zeros(3, model.nv),
            j6: DMatrix::zeros(6, model.nv),
            ..Default::default()
        };
        let joint = |name: &str| -> Result<(usize, usize)> {
            let b = model.joint_body(name)?;
            let j = &model.bodies[b].joint;
            if j.kind.nv() != 1 {
                return Err(Error::Invalid(format!(
                    "forces: joint '{name}' is not a 1-DOF joint"
                )));
            }
            Ok((j.idx_q, j.idx_v))
        };
        for s in &spec.joint_springs {
            finite(
                &format!("forces.joint_springs['{}']", s.joint),
                &[s.stiffness, s.damping, s.rest],
            )?;
            if s.stiffness < 0.0 || s.damping < 0.0 {
                return Err(Error::Invalid(format!(
                    "forces.joint_springs['{}']: stiffness and damping must be ≥ 0",
                    s.joint
                )));
            }
            let (iq, iv) = joint(&s.joint)?;
            fe.joint_springs
                .push((iq, iv, s.stiffness, s.damping, s.rest));
        }
        if spec.urdf_damping {
            for b in model.bodies.iter().skip(1) {
                let j = &b.joint;
                let d = model.limits.damping[j.idx_v];
                if j.kind.nv() == 1 && d > 0.0 {
                    fe.joint_springs.push((j.idx_q, j.idx_v, 0.0, d, 0.0));
                }
            }
        }
        for s in &spec.springs {
            finite(
                &format!("forces.springs['{}']", s.name),
                &[s.stiffness, s.damping, s.rest_length],
            )?;
            if s.stiffness < 0.0 || s.damping < 0.0 || s.rest_length < 0.0 {
                return Err(Error::Invalid(format!(
                    "forces.springs['{}']: stiffness, damping and rest_length must be ≥ 0",
                    s.name
                )));
            }
            fe.springs.push(Spring {
                a: (model.frame_id(&s.frame_a)?, Vector3::from(s.point_a)),
                b: (model.frame_id(&s.frame_b)?, Vector3::from(s.point_b)),
                k: s.stiffness,
                c: s.damping,
                rest: s.rest_length,
            });
        }
        for t in &spec.joint_torques {
            let (_, iv) = joint(&t.joint)?;
            let profile = if t.profile.is_empty() {
                vec![[0.0, t.value]]
            } else {
                t.profile.clone()
            };
            for p in &profile {
                finite(&format!("forces.joint_torques['{}']", t.joint), p)?;
            }
            if profile.windows(2).any(|w| w[1][0] <= w[0][0]) {
                return Err(Error::Invalid(format!(
                    "forces.joint_torques['{}']: profile times must increase",
                    t.joint
                )));
            }
            fe.torques.push((iv, profile));
        }
        for f in &fe_frame_forces(spec)? {
            fe.frame_forces.push(FrameForce {
                frame: model.frame_id(&f.frame)?,
                point: Vector3::from(f.point),
                force: Vector3::from(f.force),
                torque: Vector3::from(f.torque),
            });
        }
        for t in &spec.turning_resistance {
            fe.turning.push(TurningResistance::new(model, t)?);
        }
        for t in &spec.tyres {
            fe.tyres.push(Tyre::new(model, t)?);
        }
        Ok(fe)
    }

    /// True when the scene adds no force element.
    pub fn is_empty(&self) -> bool {
        self.joint_springs.is_empty()
            && self.springs.is_empty()
            && self.torques.is_empty()
            && self.frame_forces.is_empty()
            && self.turning.is_empty()
            && self.tyres.is_empty()
    }

    /// Joint spring-dampers (q index, v index, k [N/m or N·m/rad], d [N·s/m or N·m·s/rad],
    /// rest [m or rad]): `τ_v −= k (q − rest) + d v`; URDF damping folded in.
    pub fn joint_spring_dampers(&self) -> &[(usize, usize, f64, f64, f64)] {
        &self.joint_springs
    }

    /// True when the elements' generalized force depends on the state only through the joint
    /// spring-dampers (joint torques depend on t alone): its Jacobian is then (−k, −d) on
    /// those joints, with no kinematics.
    pub fn depends_on_state_by_joints_only(&self) -> bool {
        self.springs.is_empty()
            && self.frame_forces.is_empty()
            && self.turning.is_empty()
            && self.tyres.is_empty()
    }

    /// True when the generalized force needs the kinematics at (q, v): point springs, frame
    /// forces, turning resistances and tyres act at frames; joint spring-dampers and joint
    /// torques act on coordinates.
    pub fn needs_kinematics(&self) -> bool {
        !self.springs.is_empty()
            || !self.frame_forces.is_empty()
            || !self.turning.is_empty()
            || !self.tyres.is_empty()
    }

    /// Largest stiffness-like coefficient, for step-size checks: (k_max [N/m or N·m/rad], d_max).
    pub fn max_gains(&self) -> (f64, f64) {
        let k = self
            .joint_springs
            .iter()
            .map(|s| s.2)
            .chain(self.springs.iter().map(|s| s.k))
            .fold(0.0, f64::max);
        let d = self
            .joint_springs
            .iter()
            .map(|s| s.3)
            .chain(self.springs.iter().map(|s| s.c))
            .fold(0.0, f64::max);
        (k, d)
    }

    /// Add Q(t, q, v) to `tau` (kinematics of `data` must be at (q, v)).
    pub fn add_generalized_force(
        &mut self,
        model: &Model,
        data: &Data,
        t: f64,
        q: &[f64],
        v: &[f64],
        tau: &mut [f64],
    ) {
        for &(iq, iv, k, d, rest) in &self.joint_springs {
            tau[iv] -= k * (q[iq] - rest) + d * v[iv];
        }
        for (iv, profile) in &self.torques {
            tau[*iv] += piecewise_linear(profile, t);
        }
        self.add_forces_at_frames(model, data, v, tau);
    }

    /// Add the generalized force of the elements that act at frames (point springs, frame
    /// forces, turning resistances, tyres: [`Self::needs_kinematics`]) to `tau` (kinematics of
    /// `data` at (q, v)).
    pub fn add_forces_at_frames(&mut self, model: &Model, data: &Data, v: &[f64], tau: &mut [f64]) {
        for s in &self.springs {
            let pa = point_position(model, data, s.a.0, &s.a.1);
            let pb = point_position(model, data, s.b.0, &s.b.1);
            let d = pa - pb;
            let len = d.norm().max(1e-12);
            let n = d / len;
            let rate = n.dot(
                &(point_velocity(model, data, s.a.0, &s.a.1)
                    - point_velocity(model, data, s.b.0, &s.b.1)),
            );
            let f = -n * (s.k * (len - s.rest) + s.c * rate); // force on A
            add_point_force(model, data, s.a.0, &s.a.1, &f, tau);
            add_point_force(model, data, s.b.0, &s.b.1, &(-f), tau);
        }
        for ff in &self.frame_forces {
            add_point_force(model, data, ff.frame, &ff.point, &ff.force, tau);
            frame_jacobian(model, data, ff.frame, ReferenceFrame::World, &mut self.j6);
            for c in 0..model.nv {
                tau[c] += (0..3)
                    .map(|k| self.j6[(3 + k, c)] * ff.torque[k])
                    .sum::<f64>();
            }
        }
        for tr in &self.turning {
            tr.add(model, data, v, &mut self.j6, tau);
        }
        for ty in &self.tyres {
            ty.add(model, data, tau);
        }
    }

    /// The elements that act at frames alone ([`Self::add_forces_at_frames`]), `None` when
    /// there are none.
    pub fn acting_at_frames(&self) -> Option<Self> {
        self.needs_kinematics().then(|| ForceElements {
            joint_springs: vec![],
            torques: vec![],
            ..self.clone()
        })
    }

    /// The fastest rate among the elements [1/s]: max over joint elements of √(k (M⁻¹)_ii) and
    /// d (M⁻¹)_ii, over point springs of √(k w) and c w with w = n̂ᵀ J M⁻¹ Jᵀ n̂, and over
    /// turning resistances of M_max/ω₀ gᵀ M⁻¹ g with g = J_ωᵀ n, and over tyres of μ N/s₀
    /// times the contact point's tangential mobility (kinematics at q). `mobility(a)` is
    /// a M⁻¹ aᵀ for a row a (nv): the dense inverse on a small robot, ABA's factors on a large
    /// tree (`Predictor::check_step_size`).
    pub fn max_rate(
        &mut self,
        model: &Model,
        data: &Data,
        mobility: &mut dyn FnMut(&[f64]) -> f64,
    ) -> f64 {
        let mut rate: f64 = 0.0;
        let mut row = vec![0.0; model.nv];
        for &(_, iv, k, d, _) in &self.joint_springs {
            row[iv] = 1.0;
            let w = mobility(&row);
            row[iv] = 0.0;
            rate = rate.max((k * w).sqrt()).max(d * w);
        }
        for s in &self.springs {
            let pa = point_position(model, data, s.a.0, &s.a.1);
            let pb = point_position(model, data, s.b.0, &s.b.1);
            let n = (pa - pb).try_normalize(1e-12).unwrap_or(Vector3::x());
            point_jacobian(model, data, s.a.0, &s.a.1, &mut self.j3, 0);
            let ja = n.transpose() * &self.j3;
            point_jacobian(model, data, s.b.0, &s.b.1, &mut self.j3, 0);
            let jrel = ja - n.transpose() * &self.j3;
            let w = mobility(jrel.as_slice());
            rate = rate.max((s.k * w).sqrt()).max(s.c * w);
        }
        for tr in &self.turning {
            rate = rate.max(tr.max_rate(model, data, mobility, &mut self.j6));
        }
        for ty in &self.tyres {
            rate = rate.max(ty.max_rate(model, data, mobility, &mut self.j3));
        }
        rate
    }

    /// Potential energy stored in the springs [J] (kinematics of `data` at q).
    pub fn potential_energy(&self, model: &Model, data: &Data, q: &[f64]) -> f64 {
        let joints: f64 = self
            .joint_springs
            .iter()
            .map(|&(iq, _, k, _, rest)| 0.5 * k * (q[iq] - rest).powi(2))
            .sum();
        let points: f64 = self
            .springs
            .iter()
            .map(|s| {
                let len = (point_position(model, data, s.a.0, &s.a.1)
                    - point_position(model, data, s.b.0, &s.b.1))
                .norm();
                0.5 * s.k * (len - s.rest).powi(2)
            })
            .sum();
        joints + points
    }

    /// Whether any element dissipates or injects energy (dampers, torques, forces).
    pub fn is_conservative(&self) -> bool {
        self.joint_springs.iter().all(|s| s.3 == 0.0)
            && self.springs.iter().all(|s| s.c == 0.0)
            && self.torques.is_empty()
            && self.frame_forces.is_empty()
            && self.turning.is_empty()
            && self.tyres.is_empty()
    }
}

fn fe_frame_forces(spec: &ForcesSpec) -> Result<Vec<FrameForceSpec>> {
    for f in &spec.frame_forces {
        finite(
            &format!("forces.frame_forces['{}']", f.frame),
            &[f.point, f.force, f.torque].concat(),
        )?;
    }
    Ok(spec.frame_forces.clone())
}

/// `tau += J_pᵀ f`: the force `f` [N, world axes] on the material point `p` of `frame`.
pub(super) fn add_point_force(
    model: &Model,
    data: &Data,
    frame: usize,
    p: &Vector3<f64>,
    f: &Vector3<f64>,
    tau: &mut [f64],
) {
    let pw = point_position(model, data, frame, p);
    point_jacobian_transpose_add(model, data, model.frames[frame].body, &pw, f, tau);
}
