//! Turning resistance of a wide tyre (scrub): the moment about the contact normal n with which
//! the ground resists a wheel's spin about n.
//!
//! A tyre of width w touches the ground along a line across its tread (its axle direction),
//! pressed by the normal force N with uniform pressure N/w. Spinning about n at ω_n = n·ω (ω the
//! wheel's angular velocity, world axes; on level ground the chassis's yaw rate) while the wheel
//! rolls without slipping at its centre line, the point at s ∈ [−w/2, w/2] across the tread
//! slides at ω_n s along the rolling direction, and Coulomb friction μ opposes it with μ N/w ds.
//! The moment about the centre line is ∫ μ (N/w) |s| ds = μ N w / 4 (a round patch of diameter
//! w would give μ N w / 3; a wide tyre's patch is a line across the tread, hence w/4). Coulomb's
//! sign is regularised so that the dynamics stays smooth for the integrators:
//!
//!   M_n = −M_max tanh(ω_n / ω₀),   M_max = μ N w / 4,
//!
//! viscous (slope M_max/ω₀) below the spin-rate scale ω₀ and within 1 % of Coulomb above 2.65 ω₀.
//! Its power M_n ω_n ≤ 0: it only dissipates. It acts on the wheel body as a pure moment M_n n;
//! its generalized force is Q = J_ωᵀ n M_n with J_ω the angular rows of the wheel frame's world
//! Jacobian. N is the scene's constant: the wheel's share of the weight, not the contact's λ.

use crate::algorithm::{Data, ReferenceFrame, frame_jacobian};
use crate::error::{Error, Result};
use crate::model::Model;
use nalgebra::{DMatrix, Vector3};
use serde::Deserialize;

fn default_spin_rate_scale() -> f64 {
    0.1
}
fn up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// `forces.turning_resistance:` one wheel's turning resistance.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurningResistanceSpec {
    /// `wheel:` the wheel frame (a rolling contact's `wheel:`); required.
    pub wheel: String,
    /// `width:` the tyre's width w, the length of its contact line [m] > 0; required.
    pub width: f64,
    /// `friction:` Coulomb coefficient μ > 0 of the tread on the ground; required.
    pub friction: f64,
    /// `normal_force:` N, the ground's push on this wheel [N] > 0 (its share of the weight);
    /// required.
    pub normal_force: f64,
    /// `spin_rate_scale:` ω₀ [rad/s] > 0, below which the moment is viscous (default 0.1).
    #[serde(default = "default_spin_rate_scale")]
    pub spin_rate_scale: f64,
    /// `plane_normal:` the ground's normal n, world axes (normalized; default `[0, 0, 1]`).
    #[serde(default = "up")]
    pub plane_normal: [f64; 3],
}

/// A validated turning resistance.
#[derive(Clone, Debug)]
pub(crate) struct TurningResistance {
    frame: usize,
    normal: Vector3<f64>,
    /// M_max = μ N w / 4 [N·m].
    max_moment: f64,
    /// ω₀ [rad/s].
    rate_scale: f64,
}

impl TurningResistance {
    /// Validate one spec against the model; errors name the wheel and the field.
    pub(crate) fn new(model: &Model, s: &TurningResistanceSpec) -> Result<Self> {
        let at = format!("forces.turning_resistance['{}']", s.wheel);
        for (field, x) in [
            ("width", s.width),
            ("friction", s.friction),
            ("normal_force", s.normal_force),
            ("spin_rate_scale", s.spin_rate_scale),
        ] {
            if !(x.is_finite() && x > 0.0) {
                return Err(Error::Invalid(format!(
                    "{at}.{field} = {x}: must be finite and > 0"
                )));
            }
        }
        let n = Vector3::from(s.plane_normal);
        let norm = n.norm();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(Error::Invalid(format!(
                "{at}.plane_normal = {:?}: must be a finite non-zero vector",
                s.plane_normal
            )));
        }
        let frame = model
            .frame_id(&s.wheel)
            .map_err(|e| Error::Invalid(format!("{at}.wheel: {e}")))?;
        Ok(Self {
            frame,
            normal: n / norm,
            max_moment: s.friction * s.normal_force * s.width / 4.0,
            rate_scale: s.spin_rate_scale,
        })
    }

    /// g = J_ωᵀ n (nv) into row 0 of `g`: ω_n = g·v, and the moment's generalized force is g M_n.
    /// Kinematics of `data` at q.
    fn spin_row(&self, model: &Model, data: &Data, j6: &mut DMatrix<f64>) {
        frame_jacobian(model, data, self.frame, ReferenceFrame::World, j6);
        for c in 0..model.nv {
            j6[(0, c)] = (0..3).map(|k| j6[(3 + k, c)] * self.normal[k]).sum();
        }
    }

    /// Adds Q = J_ωᵀ n M_n(ω_n) to `tau` (kinematics of `data` at q).
    pub(crate) fn add(
        &self,
        model: &Model,
        data: &Data,
        v: &[f64],
        j6: &mut DMatrix<f64>,
        tau: &mut [f64],
    ) {
        self.spin_row(model, data, j6);
        let spin: f64 = (0..model.nv).map(|c| j6[(0, c)] * v[c]).sum();
        let moment = -self.max_moment * (spin / self.rate_scale).tanh();
        for (c, t) in tau.iter_mut().enumerate() {
            *t += j6[(0, c)] * moment;
        }
    }

    /// Its fastest rate [1/s]: the viscous slope M_max/ω₀ times gᵀ M⁻¹ g (kinematics at q).
    pub(crate) fn max_rate(
        &self,
        model: &Model,
        data: &Data,
        mobility: &mut dyn FnMut(&[f64]) -> f64,
        j6: &mut DMatrix<f64>,
    ) -> f64 {
        self.spin_row(model, data, j6);
        let g = j6.row(0).clone_owned();
        let w = mobility(g.as_slice());
        self.max_moment / self.rate_scale * w
    }
}
