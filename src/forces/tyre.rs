//! A tyre that grips by friction (`forces.tyres`): a wheel on the ground whose contact may creep
//! and skid, in place of a rigid rolling constraint.
//!
//! A rolling constraint holds the wheel's contact point at rest whatever force that takes. A
//! real tyre passes at most μ N to the floor: a wheel driven harder than that spins up and skids,
//! a skidding wheel also slides sideways, and under any traction force the tread creeps a little.
//! The tyre here is Coulomb friction at the contact, its sign regularised: with s the material
//! contact point's velocity in the ground plane (its slip),
//!
//!   F = −μ N s / √(|s|² + s₀²),
//!
//! applied at that point (generalized force Q = J_pᵀ F). Below the slip-speed scale s₀ it is a
//! creep of slope μ N/s₀ (a soft tyre's longitudinal and lateral stiffness against slip speed);
//! above it, within 1 % of Coulomb's μ N once |s| > 7 s₀. Its power F·s ≤ 0: it only dissipates.
//! The contact point is the wheel's lowest point, p = c + r u with u = −(n − (n·a)a)/|…| (a the
//! spin axis, n the ground's normal), as for a rolling constraint; r is the effective rolling
//! radius. A ball (no axis: a caster's sphere, a skid) touches at p = c − r n. N is the scene's
//! constant (the wheel's share of the weight; the base's coordinates hold it on the ground), or,
//! on a soft floor, N = max(0, k d + c ḋ) with d the depth of p below the plane, applied along n
//! too: a base that can pitch and leave the ground (floating) then rocks on its supports and
//! lifts its wheels, and each wheel's grip follows its load.

use super::add_point_force;
use crate::algorithm::{Data, frame_placement, point_jacobian, point_velocity};
use crate::error::{Error, Result};
use crate::model::Model;
use nalgebra::{DMatrix, Vector3};
use serde::Deserialize;

fn default_slip_speed_scale() -> f64 {
    0.01
}
fn up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// `forces.tyres:` one wheel's tyre.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TyreSpec {
    /// `wheel:` the wheel frame, its origin at the wheel's centre; required.
    pub wheel: String,
    /// `axis:` the spin axis in the wheel frame; absent for a ball (a caster's sphere, a skid)
    /// that touches the ground at its lowest point whichever way it turns.
    #[serde(default)]
    pub axis: Option<[f64; 3]>,
    /// `centre:` the wheel's or ball's centre in the frame [m] (default the frame's origin).
    #[serde(default)]
    pub centre: [f64; 3],
    /// `radius:` the effective rolling radius r [m] > 0; required.
    pub radius: f64,
    /// `friction:` Coulomb coefficient μ > 0 of the tread on the ground; required.
    pub friction: f64,
    /// `normal_force:` N, the ground's constant push on this wheel [N] > 0 (its share of the
    /// weight); required unless `normal_stiffness` is given.
    #[serde(default)]
    pub normal_force: Option<f64>,
    /// `normal_stiffness:` k [N/m] > 0: the ground pushes back N = max(0, k d + c ḋ) where the
    /// contact point lies d below the plane (a soft floor and tyre; a base that can leave the
    /// ground, floating, needs it). Default: the constant `normal_force`.
    #[serde(default)]
    pub normal_stiffness: Option<f64>,
    /// `normal_damping:` c [N·s/m] ≥ 0 of that push (default 0).
    #[serde(default)]
    pub normal_damping: f64,
    /// `plane_height:` h [m], the ground plane n·x = h (default 0).
    #[serde(default)]
    pub plane_height: f64,
    /// `slip_speed_scale:` s₀ [m/s] > 0, below which the tyre creeps viscously (default 0.01).
    #[serde(default = "default_slip_speed_scale")]
    pub slip_speed_scale: f64,
    /// `plane_normal:` the ground's normal n, world axes (normalized; default `[0, 0, 1]`).
    #[serde(default = "up")]
    pub plane_normal: [f64; 3],
}

/// Where the ground's normal force on a tyre comes from.
#[derive(Clone, Copy, Debug)]
enum Normal {
    /// The scene's constant N [N].
    Constant(f64),
    /// A soft floor: N = max(0, k d + c ḋ), d the depth below the plane n·x = h.
    Soft { k: f64, c: f64, height: f64 },
}

/// A validated tyre.
#[derive(Clone, Debug)]
pub(crate) struct Tyre {
    frame: usize,
    /// Spin axis in the frame; None for a ball.
    axis: Option<Vector3<f64>>,
    centre: Vector3<f64>,
    radius: f64,
    normal: Vector3<f64>,
    friction: f64,
    normal_force: Normal,
    /// s₀ [m/s].
    slip_scale: f64,
}

fn unit(at: &str, field: &str, x: [f64; 3]) -> Result<Vector3<f64>> {
    let v = Vector3::from(x);
    let norm = v.norm();
    if !(norm.is_finite() && norm > 1e-9) {
        return Err(Error::Invalid(format!(
            "{at}.{field} = {x:?}: must be a finite non-zero vector"
        )));
    }
    Ok(v / norm)
}

impl Tyre {
    /// Whether this is a wheel's tyre (it has a spin axis) on frame `frame`.
    pub(crate) fn is_wheel_on(&self, frame: usize) -> bool {
        self.frame == frame && self.axis.is_some()
    }

    /// Validate one spec against the model; errors name the wheel and the field.
    pub(crate) fn new(model: &Model, s: &TyreSpec) -> Result<Self> {
        let at = format!("forces.tyres['{}']", s.wheel);
        let positive = [
            ("radius", Some(s.radius)),
            ("friction", Some(s.friction)),
            ("normal_force", s.normal_force),
            ("normal_stiffness", s.normal_stiffness),
            ("slip_speed_scale", Some(s.slip_speed_scale)),
        ];
        for (field, x) in positive.iter().filter_map(|(f, x)| x.map(|x| (f, x))) {
            if !(x.is_finite() && x > 0.0) {
                return Err(Error::Invalid(format!(
                    "{at}.{field} = {x}: must be finite and > 0"
                )));
            }
        }
        for (field, x, least) in [
            ("normal_damping", s.normal_damping, 0.0),
            ("plane_height", s.plane_height, f64::NEG_INFINITY),
        ] {
            if !(x.is_finite() && x >= least) {
                return Err(Error::Invalid(format!(
                    "{at}.{field} = {x}: must be finite{}",
                    if least == 0.0 { " and ≥ 0" } else { "" }
                )));
            }
        }
        crate::error::check_finite(&format!("{at}.centre"), &s.centre)?;
        let normal_force = match (s.normal_force, s.normal_stiffness) {
            (_, Some(k)) => Normal::Soft {
                k,
                c: s.normal_damping,
                height: s.plane_height,
            },
            (Some(n), None) => Normal::Constant(n),
            (None, None) => {
                return Err(Error::Invalid(format!(
                    "{at}: needs normal_force [N] or normal_stiffness [N/m]"
                )));
            }
        };
        let frame = model
            .frame_id(&s.wheel)
            .map_err(|e| Error::Invalid(format!("{at}.wheel: {e}")))?;
        Ok(Self {
            frame,
            axis: s.axis.map(|a| unit(&at, "axis", a)).transpose()?,
            centre: Vector3::from(s.centre),
            radius: s.radius,
            normal: unit(&at, "plane_normal", s.plane_normal)?,
            friction: s.friction,
            normal_force,
            slip_scale: s.slip_speed_scale,
        })
    }

    /// The contact point c + r u in the frame [m] (c the centre; u the direction from it to the
    /// ground: −n for a ball), the material point that touches the ground now, and its height
    /// n·p above the origin, world axes [m] (kinematics of `data` at q).
    fn contact_point(&self, model: &Model, data: &Data) -> (Vector3<f64>, f64) {
        let o_m_w = frame_placement(model, data, self.frame);
        let u = match self.axis {
            Some(axis) => {
                let a = o_m_w.rotation * axis;
                let w = self.normal - a * self.normal.dot(&a);
                -w / w.norm().max(f64::MIN_POSITIVE)
            }
            None => -self.normal,
        };
        let local = self.centre + o_m_w.rotation.transpose() * (u * self.radius);
        let height = self
            .normal
            .dot(&(o_m_w.translation + o_m_w.rotation * local));
        (local, height)
    }

    /// The ground's normal force N [N] at a contact point at `height` moving at `vp`.
    fn normal_force(&self, height: f64, vp: &Vector3<f64>) -> f64 {
        match self.normal_force {
            Normal::Constant(n) => n,
            Normal::Soft { k, c, height: h } => {
                let depth = h - height;
                if depth <= 0.0 {
                    0.0
                } else {
                    (k * depth - c * self.normal.dot(vp)).max(0.0)
                }
            }
        }
    }

    /// Adds Q = J_pᵀ (N n + F(s)) to `tau`, s the contact point's velocity in the ground plane
    /// (kinematics of `data` at (q, v)); a constant N is not applied along n (the base's
    /// coordinates already hold the wheel on the ground).
    pub(crate) fn add(&self, model: &Model, data: &Data, tau: &mut [f64]) {
        let (p, f, n) = self.ground_force(model, data);
        if n == 0.0 {
            return;
        }
        let f = match self.normal_force {
            Normal::Soft { .. } => f + self.normal * n,
            Normal::Constant(_) => f,
        };
        add_point_force(model, data, self.frame, &p, &f, tau);
    }

    /// The tread's friction F(s) in the ground plane, world axes [N] (kinematics of `data` at
    /// (q, v)), with the contact point in the frame [m] and N [N].
    fn ground_force(&self, model: &Model, data: &Data) -> (Vector3<f64>, Vector3<f64>, f64) {
        let (p, height) = self.contact_point(model, data);
        let vp = point_velocity(model, data, self.frame, &p);
        let n = self.normal_force(height, &vp);
        let s = vp - self.normal * self.normal.dot(&vp);
        let scale = self.friction * n / (s.norm_squared() + self.slip_scale.powi(2)).sqrt();
        (p, -s * scale, n)
    }

    /// |F(s)|, the friction the tread passes to the ground [N] (kinematics at (q, v)).
    pub(crate) fn friction_force(&self, model: &Model, data: &Data) -> f64 {
        self.ground_force(model, data).1.norm()
    }

    /// Its fastest rate [1/s]: the creep slope μ N/s₀ times the largest tangential mobility
    /// of the contact point, bounded by the trace of P J M⁻¹ Jᵀ P (P = I − n nᵀ; kinematics at
    /// q).
    pub(crate) fn max_rate(
        &self,
        model: &Model,
        data: &Data,
        mobility: &mut dyn FnMut(&[f64]) -> f64,
        j3: &mut DMatrix<f64>,
    ) -> f64 {
        let (p, height) = self.contact_point(model, data);
        point_jacobian(model, data, self.frame, &p, j3, 0);
        let proj = nalgebra::Matrix3::identity() - self.normal * self.normal.transpose();
        let jt = proj * j3.rows(0, 3);
        // The trace of P J M⁻¹ Jᵀ P: the sum of its rows' mobilities.
        let tangential: f64 = (0..3)
            .map(|i| mobility(jt.row(i).clone_owned().as_slice()))
            .sum();
        let jn = self.normal.transpose() * j3.rows(0, 3);
        let normal_mobility = mobility(jn.as_slice());
        let vp = point_velocity(model, data, self.frame, &p);
        let n = self.normal_force(height, &vp);
        let (k, c) = match self.normal_force {
            Normal::Soft { k, c, .. } => (k, c),
            Normal::Constant(_) => (0.0, 0.0),
        };
        (self.friction * n / self.slip_scale * tangential)
            .max((k * normal_mobility).sqrt())
            .max(c * normal_mobility)
    }
}
