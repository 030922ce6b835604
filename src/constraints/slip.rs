//! The slip test of a rolling contact: does the tangential force it needs exceed μ·N?
//!
//! A rolling constraint holds the wheel without slipping whatever force that takes; a real
//! tyre grips only while |f_t| ≤ μ N (Coulomb). The constraint force tells how far a
//! prediction is from that limit. Where the base type holds the height (a planar base), the
//! model has no normal row and N is taken from the test's fallback (by default the weight
//! shared equally by the rolling contacts).

use super::{ConstraintForce, ConstraintKind, ConstraintSet, ContactLimits};
use crate::model::Model;

/// Coulomb's rule for rolling contacts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipTest {
    /// Friction coefficient μ [-].
    pub friction_coefficient: f64,
    /// Normal force used where the contact has no normal row (planar base) [N].
    pub fallback_normal_force: f64,
}

/// The verdict on one rolling contact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipVerdict {
    /// Normal force N used [N] (the contact's, or the test's fallback).
    pub normal_force: f64,
    /// Magnitude of the tangential force the contact needs [N].
    pub tangential_force: f64,
    /// |f_t| > μ N.
    pub slipping: bool,
}

impl SlipTest {
    /// μ with a fallback normal force: `planar_normal_force` [N] when positive, else the
    /// model's weight m·|g| shared equally by the set's rolling contacts.
    pub fn new(
        model: &Model,
        constraints: &ConstraintSet,
        friction_coefficient: f64,
        planar_normal_force: f64,
    ) -> Self {
        let n_rolling = constraints
            .items
            .iter()
            .filter(|c| c.kind() == ConstraintKind::Rolling)
            .count();
        let fallback_normal_force = if planar_normal_force > 0.0 {
            planar_normal_force
        } else {
            model.total_mass() * model.gravity.norm() / n_rolling.max(1) as f64
        };
        SlipTest {
            friction_coefficient,
            fallback_normal_force,
        }
    }

    /// What a prediction's contact judgement assumes under this test (the ROS nodes' rule):
    /// μ for the contacts that declare none, and the fallback normal force for the wheels
    /// without a normal row. A contact's own `friction:` still wins (predict/contacts.rs).
    pub fn contact_limits(&self) -> ContactLimits {
        ContactLimits {
            friction: Some(self.friction_coefficient),
            normal_force: Some(self.fallback_normal_force),
        }
    }

    /// The verdict on `f`; `None` for constraints that are not rolling contacts.
    pub fn judge(&self, f: &ConstraintForce) -> Option<SlipVerdict> {
        if f.kind != ConstraintKind::Rolling {
            return None;
        }
        let tangential_force = f.tangential_force.unwrap_or(0.0);
        let normal_force = match f.normal_force {
            Some(n) if n.is_finite() => n,
            _ => self.fallback_normal_force,
        };
        Some(SlipVerdict {
            normal_force,
            tangential_force,
            slipping: tangential_force > self.friction_coefficient * normal_force,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn contact(normal: f64) -> ConstraintForce {
        ConstraintForce {
            name: "c".into(),
            kind: ConstraintKind::Rolling,
            frame: "wheel".into(),
            frame_origin_world: Some([0.0, 0.0, 0.05]),
            axes: "world".into(),
            rows: vec![],
            lambda: vec![],
            force: [2.0, 0.0, 10.0],
            torque: [0.0, 0.0, 0.0],
            point_world: [0.0, 0.0, 0.0],
            position_residual: vec![],
            velocity_residual: vec![],
            normal_force: Some(normal),
            tangential_force: Some(2.0),
            generalized_force: None,
        }
    }

    #[test]
    fn coulomb_rule_and_planar_fallback() {
        let f = contact(10.0);
        let test = SlipTest {
            friction_coefficient: 0.1,
            fallback_normal_force: 1.0,
        };
        // |f_t| = 2 N > 0.1 · 10 N.
        let v = test.judge(&f).unwrap();
        assert_eq!(
            (v.normal_force, v.tangential_force, v.slipping),
            (10.0, 2.0, true)
        );
        let test = SlipTest {
            friction_coefficient: 0.5,
            ..test
        };
        assert!(!test.judge(&f).unwrap().slipping);
        // At the limit |f_t| = μ N (2 N = 0.25 · 8 N, exact in binary) the tyre still grips.
        let at_limit = SlipTest {
            friction_coefficient: 0.25,
            ..test
        };
        assert!(!at_limit.judge(&contact(8.0)).unwrap().slipping);
        // No normal row (planar base): N is the fallback, 2 N > 0.5 · 1 N.
        let v = test.judge(&contact(f64::NAN)).unwrap();
        assert_eq!((v.normal_force, v.slipping), (1.0, true));
        let weld = ConstraintForce {
            kind: ConstraintKind::Weld,
            ..f
        };
        assert!(test.judge(&weld).is_none());
    }

    #[test]
    fn wrench_moves_to_the_frame_origin() {
        // Contact 0.05 m below the wheel centre: τ_o = (p − o) × f = (0, 0, −0.05) × (2, 0, 10)
        // = (0, −0.1, 0).
        let w = contact(10.0).wrench_at_frame_origin();
        assert_eq!([w.ang.x, w.ang.y, w.ang.z], [0.0, -0.1, 0.0]);
        assert_eq!([w.lin.x, w.lin.y, w.lin.z], [2.0, 0.0, 10.0]);
    }
}
