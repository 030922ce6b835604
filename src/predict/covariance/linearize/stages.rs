//! The dynamics at the stages of a linearized step: q̈ and its derivatives under the step's
//! generalized force, with the joint springs' and controllers' share moved to the stage.

use super::Linearization;
use super::frame_forces::FrameForces;
use crate::derivatives::{DerivativeData, aba_derivatives, constrained_dynamics_derivatives};
use crate::dynamics::{Baumgarte, Formulation, KktOptions};
use crate::error::Result;
use crate::system::{DynamicsOptions, System};

/// q̈ and its derivatives at (q, v, τ) into `dd`: the multiplier form's with constraints (its
/// Baumgarte gains included), ABA's without. With joint spring-dampers, τ's share of them is
/// taken at this (q, v) (τ holds the share at the step's start (q₀, v₀)) and their stiffness and
/// damping enter ∂q̈/∂q and ∂q̈/∂v through ∂q̈/∂τ; so do the elements acting at frames, moved
/// to the stage and differentiated there (frame_forces.rs).
#[allow(clippy::too_many_arguments)]
pub(super) fn dynamics(
    sys: &mut System,
    at: KktOptions,
    dd: &mut DerivativeData,
    springs: &[(usize, usize, f64, f64, f64)],
    frame: Option<&mut FrameForces>,
    tau_stage: &mut [f64],
    (q0, v0): (&[f64], &[f64]),
    (q, v, ds): (&[f64], &[f64], f64),
    tau: &[f64],
) -> Result<()> {
    stage_torque(springs, tau_stage, (q0, v0), (q, v, ds), tau);
    let at = KktOptions { t: at.t + ds, ..at };
    if let Some(f) = frame {
        f.stage(sys, (q, v), tau_stage, true);
        dynamics_derivatives(sys, at, dd, q, v, tau_stage)?;
        f.add_to(dd);
    } else {
        dynamics_derivatives(sys, at, dd, q, v, tau_stage)?;
    }
    let nv = v.len();
    for &(_, iv, k, d, _) in springs {
        for i in 0..nv {
            let g = dd.dqdd_dtau[(i, iv)];
            dd.dqdd_dq[(i, iv)] -= g * k;
            dd.dqdd_dv[(i, iv)] -= g * d;
        }
    }
    Ok(())
}

impl Linearization {
    /// The generalized force a step held from (q0, v0) under `tau` reaches at (q, v), `ds`
    /// [s] later, into `out`: the joint springs' and controllers' share and the elements acting
    /// at frames moved there, as a stage takes them. The τ to hold over a step that starts
    /// within a recorded one (Radau5's substeps, covariance/substeps.rs).
    pub(in crate::predict) fn torque_at(
        &mut self,
        sys: &mut System,
        (q0, v0): (&[f64], &[f64]),
        tau: &[f64],
        (q, v, ds): (&[f64], &[f64], f64),
        out: &mut [f64],
    ) {
        stage_torque(&self.joint_springs, out, (q0, v0), (q, v, ds), tau);
        if let Some(f) = self.frame_forces.as_mut() {
            f.start_step(sys, q0, v0);
            f.stage(sys, (q, v), out, false);
        }
    }
}

/// The generalized force at a stage (q, v) `ds` [s] into the step: the step's τ, with each
/// joint spring's and controller's share moved from the start (q0, v0) to the stage
/// (−k Δq − d Δv) and a controller's own rate (its `Feedback::rate`) added over ds.
fn stage_torque(
    springs: &[(usize, usize, f64, f64, f64)],
    tau_stage: &mut [f64],
    (q0, v0): (&[f64], &[f64]),
    (q, v, ds): (&[f64], &[f64], f64),
    tau: &[f64],
) {
    tau_stage.copy_from_slice(tau);
    for &(iq, iv, k, d, rate) in springs {
        tau_stage[iv] -= k * (q[iq] - q0[iq]) + d * (v[iv] - v0[iv]);
        if rate != 0.0 {
            tau_stage[iv] += rate * ds;
        }
    }
}

/// q̈ alone at the stage (q, v) under τ and the joint springs measured from (q0, v0) (as in
/// [`dynamics`]), into `qdd`: a plain evaluation, solved as the prediction solves a stage.
#[allow(clippy::too_many_arguments)]
pub(super) fn stage_acceleration(
    sys: &mut System,
    at: KktOptions,
    springs: &[(usize, usize, f64, f64, f64)],
    frame: Option<&mut FrameForces>,
    tau_stage: &mut [f64],
    (q0, v0): (&[f64], &[f64]),
    (q, v, ds): (&[f64], &[f64], f64),
    tau: &[f64],
    qdd: &mut [f64],
) -> Result<()> {
    stage_torque(springs, tau_stage, (q0, v0), (q, v, ds), tau);
    if let Some(f) = frame {
        f.stage(sys, (q, v), tau_stage, false);
    }
    let opts = DynamicsOptions {
        gains: Some(at.gains),
        t: at.t + ds,
        ..DynamicsOptions::stage(sys.formulation())
    };
    qdd.copy_from_slice(sys.forward_dynamics_with(q, v, tau_stage, opts)?.as_slice());
    Ok(())
}

/// How a stage is evaluated at time `t` [s] with Baumgarte `gains`: its rows solved as the
/// prediction solves a stage's (`DynamicsOptions::stage`): redundant rows that disagree there
/// get the least-squares λ, whose derivatives `derivatives::kkt` takes.
pub(in crate::predict) fn stage_options(t: f64, gains: Baumgarte) -> KktOptions {
    KktOptions {
        t,
        gains,
        allow_inconsistent: DynamicsOptions::stage(Formulation::Multipliers).allow_inconsistent,
        rows_evaluated: false,
    }
}

/// q̈ and ∂q̈/∂(q, v, τ) at (q, v, τ) into `dd` under `at` ([`stage_options`]): the multiplier
/// form's (its Baumgarte gains included) with constraints, ABA's without.
pub(in crate::predict) fn dynamics_derivatives(
    sys: &mut System,
    at: KktOptions,
    dd: &mut DerivativeData,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) -> Result<()> {
    let p = sys.parts();
    if p.constraints.is_empty() {
        aba_derivatives(p.model, p.data, dd, q, v, tau)
    } else {
        constrained_dynamics_derivatives(
            p.model,
            p.data,
            p.constraints,
            p.rows,
            p.multipliers,
            dd,
            q,
            v,
            tau,
            at,
        )
    }
}
