//! The limits of a contact that cannot be checked: what a contact (constraints/contact.rs)
//! does not declare is listed, never guessed.

use super::LimitKind;
use crate::constraints::{Contact, ContactLimits};

/// The limits of `contact` that cannot be checked under `limits`: lift-off without a normal
/// row, friction without μ or a normal force (in that order).
pub fn unchecked_contact_limits(
    contact: &Contact,
    limits: &ContactLimits,
) -> impl Iterator<Item = LimitKind> {
    let lift_off = contact.normal.is_none();
    let friction = !contact.tangential.is_empty() && contact.friction_under(limits).is_none();
    [
        lift_off.then_some(LimitKind::LiftOff),
        friction.then_some(LimitKind::Friction),
    ]
    .into_iter()
    .flatten()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wheel_without_a_normal_row_never_checks_lift_off_and_checks_friction_with_an_assumed_n() {
        // A wheel with tangential rows 0, 1 and no normal row (planar base), no μ of its own.
        let planar = Contact {
            name: "w".into(),
            normal: None,
            tangential: vec![0, 1],
            friction: None,
            sideways_tyre: None,
        };
        let assumed = ContactLimits {
            friction: Some(1.0),
            normal_force: None,
        };
        let kinds: Vec<_> = unchecked_contact_limits(&planar, &assumed).collect();
        assert_eq!(kinds, [LimitKind::LiftOff, LimitKind::Friction]);
        let both = ContactLimits {
            normal_force: Some(4.0),
            ..assumed
        };
        let kinds: Vec<_> = unchecked_contact_limits(&planar, &both).collect();
        assert_eq!(kinds, [LimitKind::LiftOff]);
    }
}
