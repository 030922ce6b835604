//! What `/diagnostics` says of the contacts along the last prediction: its first slip or
//! lift-off as a WARN ("slip at t=0.42 s on left_wheel_contact (friction used 1.3 × μ)"), and the
//! limits it could not check. The core judges every sample (`Trajectory::contact_check`); μ is a
//! contact's own `friction:`, else `slip.friction_coefficient`, and a wheel without a normal row
//! (planar base) takes the slip test's normal force (`SlipTest::contact_limits`, the one rule
//! shared with `~/constraint_forces`).

use constraint_dynamics::constraints::BreakKind;
use constraint_dynamics::predict::{ContactBreak, ContactCheck};

/// The WARN of a predicted break.
pub fn warning(b: &ContactBreak) -> String {
    match b.kind {
        BreakKind::Slip => {
            let used = match b.friction_used {
                Some(x) => format!("friction used {x:.2} × μ"),
                None => format!("normal force {:.3} N, no grip", b.normal_force),
            };
            format!("slip at t={:.2} s on {} ({used})", b.t, b.contact)
        }
        BreakKind::LiftOff => format!(
            "lift-off at t={:.2} s on {} (it would have to pull with {:.3} N)",
            b.t, b.contact, -b.normal_force
        ),
    }
}

/// The `/diagnostics` values of a check: the first break ("none within the horizon") and the
/// unchecked limits ("lift_off: left_wheel_contact, …").
pub fn values(check: &ContactCheck) -> [(&'static str, String); 2] {
    let first = match &check.first_break {
        Some(b) => warning(b),
        None => "none within the horizon".into(),
    };
    let unchecked: Vec<String> = (check.unchecked.iter())
        .map(|u| format!("{}: {}", u.kind, u.name))
        .collect();
    [
        ("predicted contact break", first),
        ("unchecked contact limits", unchecked.join(", ")),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use constraint_dynamics::robot_limits::NamedLimit;

    #[test]
    fn a_break_reads_as_the_warning_and_the_values_name_it() {
        let slip = ContactBreak {
            t: 0.42,
            contact: "left_wheel_contact".into(),
            kind: BreakKind::Slip,
            friction_used: Some(1.3),
            normal_force: 150.0,
        };
        assert_eq!(
            warning(&slip),
            "slip at t=0.42 s on left_wheel_contact (friction used 1.30 × μ)"
        );
        let lift = ContactBreak {
            t: 0.34,
            contact: "caster_contact".into(),
            kind: BreakKind::LiftOff,
            friction_used: None,
            normal_force: -1.4019,
        };
        assert_eq!(
            warning(&lift),
            "lift-off at t=0.34 s on caster_contact (it would have to pull with 1.402 N)"
        );
        let check = ContactCheck {
            contacts: vec!["left_wheel_contact".into()],
            unchecked: vec![NamedLimit {
                kind: "lift_off",
                name: "left_wheel_contact".into(),
            }],
            first_break: None,
        };
        let [first, unchecked] = values(&check);
        assert_eq!(first.1, "none within the horizon");
        assert_eq!(unchecked.1, "lift_off: left_wheel_contact");
    }
}
