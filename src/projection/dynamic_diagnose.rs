//! Why a dynamic projection is infeasible: the limits in the support of Clarabel's
//! infeasibility certificate, reduced to a set in which every limit is necessary.

use super::diagnose::Conflict;
use super::dynamic_socp::{DynSocp, SocpData, SocpOutcome};
use super::qp::IneqRow;
use crate::envelope::EnvelopeModel;
use crate::error::Result;
use crate::robot_limits::program::Row;

/// A member of the set of limits that make a dynamic request infeasible.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DynamicConflict {
    /// A constraint row, a velocity bound or a row of A (as in the kinematic projection).
    Kinematic(Conflict),
    /// Actuator k of [`EnvelopeModel::actuators`] at its effort.
    Effort(usize),
    /// Contact k of [`EnvelopeModel::contacts`] at its friction cone.
    Friction(usize),
    /// Contact k would have to pull.
    LiftOff(usize),
}

/// A limit of the cone program that a diagnosis may lift: its rows and its name.
fn groups(em: &EnvelopeModel, socp: &DynSocp) -> Vec<(std::ops::Range<usize>, DynamicConflict)> {
    let z = socp.z();
    let mut out = vec![];
    let mut r = 0;
    let rows = &socp.program.rows;
    while r < rows.len() {
        let (len, c) = match rows[r] {
            Row::Own(IneqRow::Bound(index, side)) => (
                1,
                DynamicConflict::Kinematic(Conflict::Bound { index, side }),
            ),
            Row::Own(IneqRow::User(k)) => (1, DynamicConflict::Kinematic(Conflict::Inequality(k))),
            Row::Effort(k) => (2, DynamicConflict::Effort(k)),
            Row::Normal(k) => (1, DynamicConflict::LiftOff(k)),
            Row::Cone(k) => {
                // A certificate that uses the cone's tangential part is friction's; one that
                // uses only its normal is the contact's push.
                let nt = em.contacts[k].tangential.len();
                let zt = (1..=nt).map(|t| z[r + t] * z[r + t]).sum::<f64>().sqrt();
                let c = if zt > 1e-6 * z[r].abs() {
                    DynamicConflict::Friction(k)
                } else {
                    DynamicConflict::LiftOff(k)
                };
                (1 + nt, c)
            }
            Row::Dynamics(_) | Row::Constraint(_) | Row::ConeTail => {
                r += 1;
                continue;
            }
        };
        out.push((r..r + len, c));
        r += len;
    }
    out
}

/// A minimal set of limits that cannot hold together with the dynamics and the constraints:
/// the limits in the support of Clarabel's certificate, reduced by a deletion filter (each
/// lifted in turn, and left out if the rest is still infeasible), so that every limit named is
/// necessary. Allocates and re-solves; only on infeasible requests.
pub(super) fn diagnose(
    em: &EnvelopeModel,
    socp: &mut DynSocp,
    data: &SocpData,
    out: &mut Vec<DynamicConflict>,
) -> Result<()> {
    let all = groups(em, socp);
    let z = socp.z();
    let zmax = z.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let in_support = |g: &std::ops::Range<usize>| g.clone().any(|r| z[r].abs() > 1e-7 * zmax);
    let support: Vec<bool> = all.iter().map(|(g, _)| in_support(g)).collect();
    let infeasible = |socp: &mut DynSocp| -> bool {
        matches!(socp.solve(em, data), Ok(SocpOutcome::Infeasible))
    };
    for ((g, _), &s) in all.iter().zip(&support) {
        for r in g.clone() {
            socp.relaxed[r] = !s;
        }
    }
    if !infeasible(socp) {
        socp.relaxed.fill(false);
    }
    let mut kept = vec![];
    for (k, (g, c)) in all.iter().enumerate() {
        if socp.relaxed[g.start] {
            continue;
        }
        for r in g.clone() {
            socp.relaxed[r] = true;
        }
        if !infeasible(socp) {
            for r in g.clone() {
                socp.relaxed[r] = false;
            }
            kept.push(k);
            out.push(*c);
        }
    }
    socp.relaxed.fill(false);
    Ok(())
}
