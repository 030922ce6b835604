//! Contacts: the constraints whose force is limited — a rolling wheel, a unilateral or frictional
//! point contact — and which of their rows are normal and tangential. The acceleration envelope
//! (as constraints of its cone program) and the prediction (as a judgement of each sample's λ)
//! read the same rows and the same rule:
//!
//! ```text
//! λ_n ≥ 0                the normal force pushes, never pulls (lift-off where it would pull)
//! ‖λ_t‖ ≤ μ λ_n          Coulomb's cone (slip where the motion needs more)
//! ```
//!
//! A rolling wheel's rows are (t₁, t₂, n) of its contact basis, its normal row absent where the
//! model cannot move the contact along n (a planar base holds the height). A point contact's
//! normal row is its one row when `unilateral`, else world z when it has `friction`; the other
//! rows are tangential.

use super::{Constraint, ConstraintKind, ConstraintSet};
use crate::model::Model;
use serde::Serialize;

/// A contact of a constraint set. Rows are indices into the stacked λ of the set.
#[derive(Clone, Debug, PartialEq)]
pub struct Contact {
    /// The constraint's name.
    pub name: String,
    /// The row of the normal force, which pushes and never pulls (λ_n ≥ 0); `None` where the
    /// model has no such row (a wheel on a planar base: the base holds the height).
    pub normal: Option<usize>,
    /// The rows of the tangential force (t₁, t₂ of a wheel; x, y of a point contact).
    pub tangential: Vec<usize>,
    /// Coulomb coefficient μ: ‖λ_t‖ ≤ μ λ_n (a second-order cone) when given with a normal row.
    pub friction: Option<f64>,
    /// The wheel frame whose tyre (`forces.tyres`) holds this contact sideways (`lateral:
    /// tyre`): the tyre's friction is tangential force the contact carries outside λ.
    pub sideways_tyre: Option<usize>,
}

/// What a caller assumes where a contact declares less than its judgement needs. The default
/// assumes nothing: such limits are listed unchecked, never guessed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactLimits {
    /// μ [-] of the contacts that declare no `friction:` (the ROS nodes'
    /// `slip.friction_coefficient`); `None`: their friction is unchecked.
    pub friction: Option<f64>,
    /// Normal force [N] of a contact without a normal row (a wheel on a planar base: the nodes'
    /// `slip.planar_normal_force`, [`ContactLimits::assumed`]); `None`: its friction is
    /// unchecked. Lift-off of such a contact is never checked: nothing in the model can tell it.
    pub normal_force: Option<f64>,
}

impl ContactLimits {
    /// μ `friction` [-] for the contacts of `set` that declare none, and as the normal force of
    /// a wheel without a normal row `planar_normal_force` [N] when positive, else the model's
    /// weight m·|g| shared equally by the set's rolling contacts (the ROS nodes' `slip.*`).
    pub fn assumed(
        model: &Model,
        set: &ConstraintSet,
        friction: f64,
        planar_normal_force: f64,
    ) -> Self {
        let rolling = (set.items.iter())
            .filter(|c| c.kind() == ConstraintKind::Rolling)
            .count();
        let normal_force = match planar_normal_force > 0.0 {
            true => planar_normal_force,
            false => model.total_mass() * model.gravity.norm() / rolling.max(1) as f64,
        };
        ContactLimits {
            friction: Some(friction),
            normal_force: Some(normal_force),
        }
    }
}

/// How a contact breaks ideal rolling (or sticking).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BreakKind {
    /// The motion needs more friction than μ: ‖λ_t‖ > μ N.
    Slip,
    /// The normal force would have to pull: λ_n < 0.
    LiftOff,
}

/// A contact judged at one λ.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ContactState {
    /// The normal force N [N]: λ_n, or the assumed one ([`ContactLimits::normal_force`]);
    /// absent where neither exists.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal_force: Option<f64>,
    /// The tangential force the contact carries [N]: ‖λ_t‖, with a sideways tyre's friction.
    pub tangential_force: f64,
    /// Friction used, the tangential force / (μ N) [-] (> 1: slip); absent where friction is
    /// unchecked or N ≤ 0.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub friction_used: Option<f64>,
    /// How the contact breaks at this λ, if it does.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub breaks: Option<BreakKind>,
}

impl Contact {
    /// Judge this contact at the stacked multipliers `lambda` (nc) under `limits`, with
    /// `sideways` [N] the friction its sideways tyre passes (0 without one), at right angles to
    /// its rows: the tangential force is ‖(λ_t, sideways)‖. Lift-off when λ_n <
    /// −`pull_tolerance` [N] (a contact that carries nothing may read a rounding error below
    /// zero); else slip when the tangential force exceeds μ max(N, 0) (at μ N the contact still
    /// grips: Coulomb's cone is closed). Allocates nothing.
    pub fn judge(
        &self,
        lambda: &[f64],
        sideways: f64,
        limits: &ContactLimits,
        pull_tolerance: f64,
    ) -> ContactState {
        let t = self.tangential_force(lambda).hypot(sideways);
        let row_normal = self.normal.map(|r| lambda[r]);
        if let Some(n) = row_normal.filter(|&n| n < -pull_tolerance) {
            return ContactState {
                normal_force: Some(n),
                tangential_force: t,
                friction_used: None,
                breaks: Some(BreakKind::LiftOff),
            };
        }
        let normal_force = row_normal.or(limits.normal_force);
        let Some((mu, n)) = self.friction_under(limits).zip(normal_force) else {
            return ContactState {
                normal_force,
                tangential_force: t,
                ..ContactState::default()
            };
        };
        let friction_used = (n > 0.0 && mu > 0.0)
            .then(|| t / (mu * n))
            .filter(|x| x.is_finite());
        ContactState {
            normal_force,
            tangential_force: t,
            friction_used,
            // N within the pull tolerance below zero counts as 0: no friction to grip with,
            // and no slip without a tangential force.
            breaks: (t > mu * n.max(0.0)).then_some(BreakKind::Slip),
        }
    }

    /// ‖λ_t‖ at the stacked multipliers `lambda` (nc) [N]: the tangential force the contact's
    /// rows need.
    pub fn tangential_force(&self, lambda: &[f64]) -> f64 {
        // hypot: finite wherever the components are (a sum of squares can overflow).
        (self.tangential.iter()).fold(0.0, |m: f64, &r| m.hypot(lambda[r]))
    }

    /// Contact `k` of `set`, or `None` when the constraint limits no force (a bilateral point
    /// without `friction:`, a weld, a joint coupling, …).
    pub fn of(set: &ConstraintSet, k: usize) -> Option<Contact> {
        let r0 = set.ranges[k].start;
        let name = set.names[k].clone();
        match &set.items[k] {
            Constraint::Rolling(rc) => Some(Contact {
                name,
                normal: rc.rows.iter().position(|&r| r == 2).map(|i| r0 + i),
                tangential: (0..rc.rows.len())
                    .filter(|&i| rc.rows[i] != 2)
                    .map(|i| r0 + i)
                    .collect(),
                friction: rc.friction,
                sideways_tyre: rc.lateral_free().then_some(rc.wheel),
            }),
            Constraint::Point(pc) if pc.unilateral || pc.friction.is_some() => {
                let normal_axis = if pc.unilateral { pc.axes[0] } else { 2 };
                let normal = pc.axes.iter().position(|&a| a == normal_axis);
                Some(Contact {
                    name,
                    normal: normal.map(|i| r0 + i),
                    tangential: (0..pc.axes.len())
                        .filter(|&i| Some(i) != normal)
                        .map(|i| r0 + i)
                        .collect(),
                    friction: pc.friction,
                    sideways_tyre: None,
                })
            }
            _ => None,
        }
    }

    /// Every contact of `set`, in its order, with the index of its constraint.
    pub fn all(set: &ConstraintSet) -> Vec<(usize, Contact)> {
        (0..set.items.len())
            .filter_map(|k| Contact::of(set, k).map(|c| (k, c)))
            .collect()
    }

    /// The friction cone applies: a normal row, tangential rows and μ.
    pub fn has_cone(&self) -> bool {
        self.normal.is_some() && self.friction.is_some() && !self.tangential.is_empty()
    }

    /// μ under `limits` where friction can be judged (tangential rows, μ declared or assumed, a
    /// normal row or an assumed normal force); `None` otherwise.
    pub fn friction_under(&self, limits: &ContactLimits) -> Option<f64> {
        let normal = self.normal.is_some() || limits.normal_force.is_some();
        (normal && !self.tangential.is_empty())
            .then(|| self.friction.or(limits.friction))
            .flatten()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wheel with rows (t₁, t₂, n) at 0, 1, 2 and μ = 0.25.
    fn wheel(friction: Option<f64>, normal: Option<usize>) -> Contact {
        Contact {
            name: "w".into(),
            normal,
            tangential: vec![0, 1],
            friction,
            sideways_tyre: None,
        }
    }

    #[test]
    fn coulomb_rule_pull_tolerance_and_assumed_limits() {
        let none = ContactLimits::default();
        let w = wheel(Some(0.25), Some(2));
        // ‖(1.2, 1.6)‖ = 2 N = 0.25 · 8 N (exact in binary): at the limit the wheel grips.
        let s = w.judge(&[1.2, 1.6, 8.0], 0.0, &none, 1e-6);
        assert_eq!((s.friction_used, s.breaks), (Some(1.0), None));
        let s = w.judge(&[1.2, 1.6, 4.0], 0.0, &none, 1e-6);
        assert_eq!(
            (s.friction_used, s.breaks),
            (Some(2.0), Some(BreakKind::Slip))
        );
        // A rounding error below zero is no pull; beyond the tolerance it is.
        let s = w.judge(&[0.0, 0.0, -1e-9], 0.0, &none, 1e-6);
        assert_eq!((s.friction_used, s.breaks), (None, None));
        let s = w.judge(&[0.0, 0.0, -1e-3], 0.0, &none, 1e-6);
        assert_eq!(
            (s.normal_force, s.breaks),
            (Some(-1e-3), Some(BreakKind::LiftOff))
        );
        // Without μ nothing is judged but the sign; an assumed μ fills in, the declared one wins.
        let bare = wheel(None, Some(2));
        assert_eq!(bare.judge(&[1.2, 1.6, 4.0], 0.0, &none, 1e-6).breaks, None);
        let assumed = ContactLimits {
            friction: Some(1.0),
            normal_force: None,
        };
        assert_eq!(
            bare.judge(&[1.2, 1.6, 4.0], 0.0, &assumed, 1e-6)
                .friction_used,
            Some(0.5)
        );
        assert_eq!(
            w.judge(&[1.2, 1.6, 4.0], 0.0, &assumed, 1e-6).friction_used,
            Some(2.0)
        );
        // No normal row (planar base): lift-off never judged, friction only with an assumed N
        // (which limits stay unchecked: robot_limits/contact.rs).
        let planar = wheel(None, None);
        let both = ContactLimits {
            normal_force: Some(4.0),
            ..assumed
        };
        let s = planar.judge(&[1.2, 1.6], 0.0, &both, 1e-6);
        assert_eq!((s.normal_force, s.friction_used), (Some(4.0), Some(0.5)));
        // A wheel held sideways by its tyre: its rolling row's 1.5 N and the tyre's 2 N make
        // 2.5 N = 0.5 · 5 N, at the limit; 2.1 N sideways slips though the row alone grips.
        let rolling = Contact {
            tangential: vec![0],
            sideways_tyre: Some(7),
            ..wheel(Some(0.5), None)
        };
        let five = ContactLimits {
            normal_force: Some(5.0),
            ..none
        };
        let s = rolling.judge(&[1.5], 2.0, &five, 1e-6);
        assert_eq!(
            (s.tangential_force, s.friction_used, s.breaks),
            (2.5, Some(1.0), None)
        );
        let s = rolling.judge(&[1.5], 2.1, &five, 1e-6);
        assert_eq!(s.breaks, Some(BreakKind::Slip));
        assert_eq!(rolling.judge(&[1.5], 0.0, &five, 1e-6).breaks, None);
    }
}
