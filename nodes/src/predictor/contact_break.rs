//! What the predictor says of its contacts: on `/rosout`, each contact of the start state that
//! starts to slip or lift off ([`BreakLog`]); on `/diagnostics`, the last prediction's first slip or
//! lift-off as a WARN ("slip at t=0.42 s on left_wheel_contact (friction used 1.3 × μ)"), and the
//! limits it could not check. The core judges every sample (`Trajectory::contact_check`); μ is a
//! contact's own `friction:`, else `slip.friction_coefficient`, and a wheel without a normal row
//! (planar base) takes `slip.planar_normal_force` or its share of the weight
//! (`Robot::contact_limits`, the one rule shared with `~/constraint_forces`).

use std::time::Instant;

use constraint_dynamics::constraints::{BreakKind, Contact, ContactLimits, ContactState};
use constraint_dynamics::predict::{ContactBreak, ContactCheck};

use crate::msg::constraint_dynamics_msgs::ConstraintForces;
use crate::ros::logging::NodeLog;

/// A measured start further off the velocity constraints than this [m/s or rad/s] is quoted
/// by a slip WARN: five times the velocity noise of the bundled logs' odometry (σ 0.01 m/s),
/// a third of the skids they record (0.12–0.17 m/s, docs/logs.md).
pub const MEASURED_SLIP: f64 = 0.05;

/// How each constraint broke at the last start state, and when a break was last warned of.
pub struct BreakLog {
    last: Vec<Option<BreakKind>>,
    warned: Option<Instant>,
}

impl BreakLog {
    /// For `n` constraints, none broken.
    pub fn new(n: usize) -> Self {
        BreakLog {
            last: vec![None; n],
            warned: None,
        }
    }

    /// Logs the transitions at a new start state: a WARN when a contact starts to slip or lift
    /// off (and at most once a second while one does), an INFO when it holds again. `judged[k]`
    /// is constraint k's contact and state under `limits`, `forces` their message;
    /// `measured_off` how far off the velocity constraints the measured start lay [m/s or
    /// rad/s], which a slip WARN quotes when it is above [`MEASURED_SLIP`]: wheels and odometry
    /// that disagree are a slip the robot had, not one the prediction made up.
    pub fn update(
        &mut self,
        log: &NodeLog,
        forces: &ConstraintForces,
        judged: &[Option<(&Contact, ContactState)>],
        limits: &ContactLimits,
        measured_off: Option<f64>,
    ) {
        let measured = match measured_off {
            Some(off) if off > MEASURED_SLIP => format!(
                "; the measured start lay {off:.3} m/s off the constraints (wheels and \
                 odometry disagree: the robot was slipping)"
            ),
            _ => String::new(),
        };
        let now = Instant::now();
        let throttled = (self.warned).is_some_and(|t| now.duration_since(t).as_secs_f64() < 1.0);
        for (k, c) in forces.constraints.iter().enumerate() {
            let was = self.last.get(k).copied().flatten();
            let judged = judged.get(k).copied().flatten();
            let breaks = judged.and_then(|(_, s)| s.breaks);
            match (breaks, judged) {
                (Some(kind), Some((contact, _))) if was.is_none() || !throttled => {
                    // A slip is judged only where μ is known: the 0 never shows.
                    let mu = contact.friction_under(limits).unwrap_or(0.0);
                    log.warn(&match kind {
                        BreakKind::Slip => format!(
                            "slip: contact '{}' needs a tangential force of {:.3} N > μ·N = {mu} × \
                             {:.3} N{measured}",
                            c.name, c.tangential_force, c.normal_force
                        ),
                        BreakKind::LiftOff => format!(
                            "lift-off: contact '{}' would have to pull with {:.3} N",
                            c.name, -c.normal_force
                        ),
                    });
                    self.warned = Some(now);
                }
                (None, _) if was.is_some() => {
                    log.info(&format!("contact '{}' holds again", c.name))
                }
                _ => {}
            }
            if let Some(s) = self.last.get_mut(k) {
                *s = breaks;
            }
        }
    }
}

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
