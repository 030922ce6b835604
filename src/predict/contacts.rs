//! When ideal rolling breaks: with forces on, every sample judges each contact of the scene
//! (constraints/contact.rs: a rolling wheel, a unilateral or frictional point) at its λ — the
//! friction it uses, ‖λ_t‖ / (μ N) (with the friction of the tyre that holds a `lateral: tyre`
//! contact sideways, at right angles to its rows), and the sign of its normal force — and the
//! trajectory reports the first sample and contact where the motion would need more friction
//! than μ (`slip`) or a contact would have to pull (`lift_off`).
//!
//! The prediction itself never changes: it keeps every contact rolling whatever force that
//! takes; the judgement only reads the λ and the tyres' friction each sample already holds. The
//! ROS nodes judge the forces they publish with the same [`ContactJudge`]. μ is the contact's own
//! (`friction:`), else [`ContactLimits::friction`] of the request; N is the contact's normal
//! row, else [`ContactLimits::normal_force`] (a wheel on a planar base). What neither gives is
//! listed under [`ContactCheck::unchecked`], as the acceleration envelope lists it, never
//! guessed.

use crate::algorithm::Data;
use crate::constraints::{BreakKind, ConstraintSet, Contact, ContactLimits, ContactState};
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::model::Model;
use crate::robot_limits::{ACTIVE_TOLERANCE, NamedLimit, unchecked_contact_limits};
use serde::Serialize;

/// The first sample and contact where the predicted motion breaks ideal rolling.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ContactBreak {
    /// Time of the first sample where it breaks [s] (the break lies in the sample period
    /// before it).
    pub t: f64,
    /// The contact's constraint name.
    pub contact: String,
    /// `slip` or `lift_off`.
    pub kind: BreakKind,
    /// Friction used there, the tangential force / (μ N) [-] (> 1 at a slip); absent at a
    /// lift-off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction_used: Option<f64>,
    /// The normal force N there [N] (< 0 at a lift-off: the pull the contact would need).
    pub normal_force: f64,
}

/// The contacts' judgement over a prediction (with forces).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ContactCheck {
    /// The contacts judged, in the order of each sample's `contacts`.
    pub contacts: Vec<String>,
    /// Limits not checked: `lift_off` of a contact without a normal row (a wheel on a planar
    /// base), `friction` of one without μ (none declared nor assumed) or without a normal force.
    pub unchecked: Vec<NamedLimit>,
    /// The first break; absent when every contact holds over the horizon.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_break: Option<ContactBreak>,
}

/// A scene's contacts and the tolerance of their lift-off, built once with the predictor.
#[derive(Clone, Debug, Default)]
pub struct ContactJudge {
    /// (index of the constraint, its contact), in the scene's order.
    contacts: Vec<(usize, Contact)>,
    /// λ_n may read this far below zero before a contact counts as pulling [N]: the envelope's
    /// activity tolerance of the weight m·|g| (1 N without gravity).
    pull_tolerance: f64,
}

impl ContactJudge {
    /// The contacts of `set` on `model`.
    pub fn new(model: &Model, set: &ConstraintSet) -> Self {
        let weight = model.total_mass() * model.gravity.norm();
        let scale = if weight > 0.0 { weight } else { 1.0 };
        Self {
            contacts: Contact::all(set),
            pull_tolerance: ACTIVE_TOLERANCE * scale,
        }
    }

    /// (index of the constraint, its contact) of each contact judged, in the order of
    /// [`ContactJudge::judge`]'s states and of `Sample::contacts`.
    pub fn contacts(&self) -> &[(usize, Contact)] {
        &self.contacts
    }

    /// Each contact at `lambda` (nc), with the friction of the tyre in `tyres` that holds a
    /// contact sideways ([`Contact::sideways_tyre`]) at the kinematics of `data`, the state λ
    /// was solved at; None without contacts. One allocation (the sample's list).
    pub fn judge(
        &self,
        lambda: &[f64],
        limits: &ContactLimits,
        model: &Model,
        data: &Data,
        tyres: &ForceElements,
    ) -> Option<Vec<ContactState>> {
        (!self.contacts.is_empty()).then(|| {
            (self.contacts.iter())
                .map(|(_, c)| {
                    let sideways = (c.sideways_tyre)
                        .map_or(0.0, |wheel| tyres.wheel_tyre_friction(model, data, wheel));
                    c.judge(lambda, sideways, limits, self.pull_tolerance)
                })
                .collect()
        })
    }

    /// The check of samples judged under `limits`: the first sample (in time) and contact (in
    /// the scene's order) that breaks.
    pub(super) fn check<'a>(
        &self,
        samples: impl IntoIterator<Item = (f64, Option<&'a [ContactState]>)>,
        limits: &ContactLimits,
    ) -> ContactCheck {
        let unchecked = (self.contacts.iter())
            .flat_map(|(_, c)| {
                unchecked_contact_limits(c, limits).map(|l| NamedLimit {
                    kind: l.name(),
                    name: c.name.clone(),
                })
            })
            .collect();
        let first_break = samples.into_iter().find_map(|(t, states)| {
            let (k, s) = states?
                .iter()
                .enumerate()
                .find(|(_, s)| s.breaks.is_some())?;
            Some(ContactBreak {
                t,
                contact: self.contacts[k].1.name.clone(),
                kind: s.breaks?,
                friction_used: s.friction_used,
                // A break has a normal force: a lift-off reads its row, a slip its N.
                normal_force: s.normal_force.unwrap_or(0.0),
            })
        });
        ContactCheck {
            contacts: self.contacts.iter().map(|(_, c)| c.name.clone()).collect(),
            unchecked,
            first_break,
        }
    }
}

/// Refuse assumed limits that are not finite and ≥ 0, naming the field.
pub(super) fn validate(limits: &ContactLimits) -> Result<()> {
    for (field, x) in [
        ("friction", limits.friction),
        ("normal_force", limits.normal_force),
    ] {
        if let Some(x) = x.filter(|x| !(x.is_finite() && *x >= 0.0)) {
            return Err(Error::Invalid(format!(
                "contact_limits.{field} = {x} must be finite and ≥ 0"
            )));
        }
    }
    Ok(())
}
