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
//! radius. N is the scene's constant (the wheel's share of the weight): the wheel's coordinates
//! are free, so no constraint row carries a normal force.

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
    /// `axis:` the spin axis in the wheel frame; required.
    pub axis: [f64; 3],
    /// `radius:` the effective rolling radius r [m] > 0; required.
    pub radius: f64,
    /// `friction:` Coulomb coefficient μ > 0 of the tread on the ground; required.
    pub friction: f64,
    /// `normal_force:` N, the ground's push on this wheel [N] > 0 (its share of the weight);
    /// required.
    pub normal_force: f64,
    /// `slip_speed_scale:` s₀ [m/s] > 0, below which the tyre creeps viscously (default 0.01).
    #[serde(default = "default_slip_speed_scale")]
    pub slip_speed_scale: f64,
    /// `plane_normal:` the ground's normal n, world axes (normalized; default `[0, 0, 1]`).
    #[serde(default = "up")]
    pub plane_normal: [f64; 3],
}

/// A validated tyre.
#[derive(Clone, Debug)]
pub(crate) struct Tyre {
    frame: usize,
    axis: Vector3<f64>,
    radius: f64,
    normal: Vector3<f64>,
    /// μ N [N].
    max_force: f64,
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
    /// Validate one spec against the model; errors name the wheel and the field.
    pub(crate) fn new(model: &Model, s: &TyreSpec) -> Result<Self> {
        let at = format!("forces.tyres['{}']", s.wheel);
        for (field, x) in [
            ("radius", s.radius),
            ("friction", s.friction),
            ("normal_force", s.normal_force),
            ("slip_speed_scale", s.slip_speed_scale),
        ] {
            if !(x.is_finite() && x > 0.0) {
                return Err(Error::Invalid(format!(
                    "{at}.{field} = {x}: must be finite and > 0"
                )));
            }
        }
        let frame = model
            .frame_id(&s.wheel)
            .map_err(|e| Error::Invalid(format!("{at}.wheel: {e}")))?;
        Ok(Self {
            frame,
            axis: unit(&at, "axis", s.axis)?,
            radius: s.radius,
            normal: unit(&at, "plane_normal", s.plane_normal)?,
            max_force: s.friction * s.normal_force,
            slip_scale: s.slip_speed_scale,
        })
    }

    /// The contact point r u from the wheel's centre, in the wheel frame's axes [m]: the
    /// material point of the wheel that touches the ground now (kinematics of `data` at q).
    fn contact_point(&self, model: &Model, data: &Data) -> Vector3<f64> {
        let o_m_w = frame_placement(model, data, self.frame);
        let a = o_m_w.rotation * self.axis;
        let w = self.normal - a * self.normal.dot(&a);
        let u = -w / w.norm().max(f64::MIN_POSITIVE);
        o_m_w.rotation.transpose() * (u * self.radius)
    }

    /// The slip s: the contact point's velocity in the ground plane [m/s], world axes.
    fn slip(&self, model: &Model, data: &Data, p: &Vector3<f64>) -> Vector3<f64> {
        let vp = point_velocity(model, data, self.frame, p);
        vp - self.normal * self.normal.dot(&vp)
    }

    /// Adds Q = J_pᵀ F(s) to `tau` (kinematics of `data` at (q, v)).
    pub(crate) fn add(&self, model: &Model, data: &Data, j3: &mut DMatrix<f64>, tau: &mut [f64]) {
        let p = self.contact_point(model, data);
        let s = self.slip(model, data, &p);
        let f = -s * (self.max_force / (s.norm_squared() + self.slip_scale.powi(2)).sqrt());
        add_point_force(model, data, j3, self.frame, &p, &f, tau);
    }

    /// Its fastest rate [1/s]: the creep slope μ N/s₀ times the largest tangential mobility
    /// of the contact point, bounded by the trace of P J M⁻¹ Jᵀ P (P = I − n nᵀ; kinematics at
    /// q).
    pub(crate) fn max_rate(
        &self,
        model: &Model,
        data: &Data,
        minv: &DMatrix<f64>,
        j3: &mut DMatrix<f64>,
    ) -> f64 {
        let p = self.contact_point(model, data);
        point_jacobian(model, data, self.frame, &p, j3, 0);
        let proj = nalgebra::Matrix3::identity() - self.normal * self.normal.transpose();
        let jt = proj * j3.rows(0, 3);
        let mobility = (&jt * minv * jt.transpose()).trace();
        self.max_force / self.slip_scale * mobility
    }
}
