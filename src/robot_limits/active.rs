//! Which limits are active at an optimum of a cone program.
//!
//! Clarabel's interior-point optimum lies in the relative interior of the optimal face, so a
//! limit that is active there is active at every optimum: with redundant rows (two wheels'
//! identical lateral rows) the free split of λ between them is centred, and every contact that
//! must be at its limit is found at it. A limit is active when its slack is below
//! [`ACTIVE_TOLERANCE`] of its scale: the effort for an actuator, a force scale for a contact's
//! forces.

use super::{ACTIVE_TOLERANCE, Actuator, Binding, LimitKind};
use crate::constraints::Contact;

/// The active limits at the actuator torques `tau` (one per actuator) and constraint forces
/// `lambda` (the stacked rows the contacts index) into `out`, cleared first: efforts in the
/// actuators' order, then each contact's lift-off or friction in the contacts' order. Contact
/// forces (or impulses) are measured against `force_scale` [N, or N·s for impulses over a
/// period]. Allocates nothing once `out` holds [`max_active_limits`].
pub fn active_limits(
    actuators: &[Actuator],
    contacts: &[Contact],
    tau: &[f64],
    lambda: &[f64],
    force_scale: f64,
    out: &mut Vec<Binding>,
) {
    out.clear();
    for (k, act) in actuators.iter().enumerate() {
        if act.effort.is_finite() && act.effort - tau[k].abs() <= ACTIVE_TOLERANCE * act.effort {
            out.push(Binding {
                kind: LimitKind::Effort,
                index: k,
            });
        }
    }
    let tol = ACTIVE_TOLERANCE * force_scale;
    for (k, ct) in contacts.iter().enumerate() {
        let Some(nr) = ct.normal else { continue };
        let n = lambda[nr];
        if n <= tol {
            out.push(Binding {
                kind: LimitKind::LiftOff,
                index: k,
            });
        } else if let (true, Some(mu)) = (ct.has_cone(), ct.friction) {
            let t = ct
                .tangential
                .iter()
                .map(|&r| lambda[r] * lambda[r])
                .sum::<f64>()
                .sqrt();
            if mu * n - t <= tol {
                out.push(Binding {
                    kind: LimitKind::Friction,
                    index: k,
                });
            }
        }
    }
}

/// The most limits one optimum can name: every actuator and every contact.
pub fn max_active_limits(actuators: &[Actuator], contacts: &[Contact]) -> usize {
    actuators.len() + contacts.len()
}
