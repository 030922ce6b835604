//! What binds a limit: the constraints of the cone program active at its optimum.
//!
//! Clarabel's interior-point optimum lies in the relative interior of the optimal face, so a
//! limit that is active there is active at every optimum: with redundant rows (two wheels'
//! identical lateral rows) the free split of λ between them is centred, and every contact that
//! must be at its limit is found at it. A limit is active when its slack is below
//! [`ACTIVE_TOLERANCE`] of its scale: the effort for an actuator, the weight m·|g| for a
//! contact's forces.

use super::model::EnvelopeModel;
use super::{Binding, BindingKind};

/// Relative slack below which a limit counts as active (the program is solved to 1e-10).
pub const ACTIVE_TOLERANCE: f64 = 1e-6;

/// The active limits at x = [a; τ; λ] into `out` (cleared first; allocates nothing once `out`
/// has the capacity of every limit).
pub(super) fn active_limits(em: &EnvelopeModel, x: &[f64], out: &mut Vec<Binding>) {
    active_limits_scaled(em, x, em.force_scale, out);
}

/// [`active_limits`] with the contacts' forces (or impulses) measured against `force_scale`
/// [N, or N·s for impulses over a period]. Every limit named is pushed onto `out` after it is
/// cleared.
pub(crate) fn active_limits_scaled(
    em: &EnvelopeModel,
    x: &[f64],
    force_scale: f64,
    out: &mut Vec<Binding>,
) {
    out.clear();
    let (nv, na) = (em.nv, em.na());
    for (k, act) in em.actuators.iter().enumerate() {
        let tau = x[nv + k];
        if act.effort.is_finite() && act.effort - tau.abs() <= ACTIVE_TOLERANCE * act.effort {
            out.push(Binding {
                kind: BindingKind::Effort,
                index: k,
            });
        }
    }
    let lambda = &x[nv + na..];
    let tol = ACTIVE_TOLERANCE * force_scale;
    for (k, ct) in em.contacts.iter().enumerate() {
        let Some(nr) = ct.normal else { continue };
        let n = lambda[nr];
        if n <= tol {
            out.push(Binding {
                kind: BindingKind::LiftOff,
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
                    kind: BindingKind::Friction,
                    index: k,
                });
            }
        }
    }
}

/// The most limits one optimum can name: every actuator and every contact.
pub(crate) fn capacity(em: &EnvelopeModel) -> usize {
    em.na() + em.contacts.len()
}
