//! A rigid payload carried at run time: a mass with its centre of mass and rotational inertia,
//! attached to a named frame. [`Model::with_payload`] adds it to the spatial inertia of the body
//! that carries the frame and returns a new model; every algorithm then sees the payload
//! through that model.
//!
//! The payload's spatial inertia, given in frame F (`body_m_F` its placement in body B), is
//! `I_B += X(body_m_F) · I_F`: the centre of mass is placed in B, the rotational inertia turned
//! into B's axes (`R I_c Rᵀ`), and the sum with B's inertia shifts both to their common centre
//! of mass by the parallel-axis theorem ([`Inertia::add`]).

use super::{Model, check};
use crate::error::{Error, Result};
use crate::spatial::Inertia;
use nalgebra::{Matrix3, Vector3};
use serde::Deserialize;

/// A rigid payload: `payload:` in a scene; `mass: 0` (the default) means none.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Payload {
    /// The frame (URDF link) the payload is rigidly attached to; its body carries it.
    #[serde(default)]
    pub frame: String,
    /// Mass [kg] (≥ 0; 0 = no payload, the other fields are then ignored).
    #[serde(default)]
    pub mass: f64,
    /// Centre of mass in `frame` [m].
    #[serde(default)]
    pub com: [f64; 3],
    /// Rotational inertia about the centre of mass, `frame` axes, as
    /// `[ixx, ixy, ixz, iyy, iyz, izz]` [kg·m²] (URDF's `<inertia>` entries).
    #[serde(default)]
    pub inertia: [f64; 6],
}

impl Payload {
    /// A point mass `mass` [kg] at `com` [m] in `frame`.
    pub fn point(frame: &str, mass: f64, com: [f64; 3]) -> Self {
        Payload {
            frame: frame.to_string(),
            mass,
            com,
            inertia: [0.0; 6],
        }
    }

    /// True when there is no payload (mass 0).
    pub fn is_none(&self) -> bool {
        self.mass == 0.0
    }

    /// The rotational inertia about the centre of mass as a symmetric 3 × 3 matrix [kg·m²].
    pub fn inertia_matrix(&self) -> Matrix3<f64> {
        let [xx, xy, xz, yy, yz, zz] = self.inertia;
        Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
    }

    /// Checks the numbers without a model: finite and at most [`super::MAX_URDF_MAGNITUDE`],
    /// mass ≥ 0, and a rotational inertia a rigid body can have (positive semidefinite,
    /// principal moments satisfying the triangle inequalities). Errors name the field
    /// (`payload.mass`, `payload.com`, `payload.inertia`).
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, why: String| Error::Invalid(format!("payload.{field}: {why}"));
        let limit = super::MAX_URDF_MAGNITUDE;
        let m = self.mass;
        if !m.is_finite() || !(0.0..=limit).contains(&m) {
            return Err(bad(
                "mass",
                format!("{m} kg must be finite, ≥ 0 and ≤ {limit:e}"),
            ));
        }
        for (field, values) in [("com", &self.com[..]), ("inertia", &self.inertia[..])] {
            if let Some(x) = values.iter().find(|x| !x.is_finite() || x.abs() > limit) {
                return Err(bad(
                    field,
                    format!("{values:?}: entry {x} is not finite or exceeds {limit:e}"),
                ));
            }
        }
        if let Some(why) = check::inertia_defect(m, &self.inertia_matrix()) {
            // inertia_defect speaks of URDF's element; here it is the payload's field.
            return Err(bad("inertia", why.replace("<inertia> ", "")));
        }
        Ok(())
    }

    /// "2.0 kg on tool0", or "none".
    pub fn describe(&self) -> String {
        match self.is_none() {
            true => "none".into(),
            false => format!("{:?} kg on {}", self.mass, self.frame),
        }
    }
}

impl Model {
    /// This model carrying `payload`: the body that carries `payload.frame` gains the payload's
    /// spatial inertia (see the module documentation); everything else is unchanged. A payload
    /// of mass 0 returns the model as it is. Errors name `payload.frame` (unknown frame) or the
    /// bad field ([`Payload::validate`]).
    ///
    /// A payload on a frame fixed to the world (a fixed base's root link) moves with nothing:
    /// the model is unchanged but for a warning in [`Model::warnings`].
    pub fn with_payload(&self, payload: &Payload) -> Result<Model> {
        payload.validate()?;
        let mut model = self.clone();
        if payload.is_none() {
            return Ok(model);
        }
        let f = self.frame_id(&payload.frame).map_err(|e| {
            Error::Invalid(format!(
                "payload.frame: {e}; the payload must sit on a frame of the model"
            ))
        })?;
        let frame = &self.frames[f];
        if frame.body == 0 {
            model.warnings.push(format!(
                "payload of {} kg on '{}', which is fixed to the world: it changes no dynamics",
                payload.mass, payload.frame
            ));
            return Ok(model);
        }
        let in_frame = Inertia::new(
            payload.mass,
            Vector3::from(payload.com),
            payload.inertia_matrix(),
        );
        let body = &mut model.bodies[frame.body];
        body.inertia = body.inertia.add(&in_frame.transformed(&frame.placement));
        // Adding a physical inertia can only make M more definite: only a model that was
        // singular needs its check again (a payload on a massless link can cure it).
        if let Some(s) = &self.singular {
            model.singular = check::singular_joint(&model, &s.file);
        }
        Ok(model)
    }
}
