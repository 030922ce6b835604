//! The guards of a prediction: its work limits, checked before running, and the energy check of
//! fixed explicit steps on passive, conservative scenes, and the explicit methods' stability limit
//! for the stiffest force element.

use super::IntegrationSettings;
use super::integrator::Method;
use super::trajectory::Sample;
use crate::algorithm::{crba, forward_kinematics};
use crate::error::{Error, Result};
use crate::model::Model;

/// `max_energy_error`: for a passive, conservative scene stepped by a fixed explicit method, the
/// energy may not move by more than this fraction of the energy in motion (the largest kinetic
/// plus spring energy, or gravity energy exchanged, seen so far), checked at every sample from the
/// 16th step on: past it the step is too large and the answer would be wrong, so the prediction stops with
/// `Error::Diverged` instead.
pub(super) struct EnergyGuard {
    on: bool,
    e0: f64,
    pe0: f64,
    scale: f64,
}

impl EnergyGuard {
    /// Over the first steps from rest a first-order method's relative energy error is O(1) by
    /// nature (semi-implicit Euler's first step loses half the kinetic energy it creates).
    const MIN_STEPS: usize = 16;

    /// `springs`: the spring part of the sample's potential energy (≥ 0, zero at rest length).
    pub(super) fn new(first: &Sample, springs: f64, on: bool) -> Self {
        Self {
            on,
            e0: first.kinetic_energy + first.potential_energy,
            pe0: first.potential_energy - springs,
            scale: first.kinetic_energy + springs,
        }
    }

    pub(super) fn check(
        &mut self,
        x: &Sample,
        springs: f64,
        steps: usize,
        s: &IntegrationSettings,
    ) -> Result<()> {
        if !self.on {
            return Ok(());
        }
        self.scale = self
            .scale
            .max(x.kinetic_energy + springs)
            .max((x.potential_energy - springs - self.pe0).abs());
        if steps < Self::MIN_STEPS {
            return Ok(());
        }
        let de = x.kinetic_energy + x.potential_energy - self.e0;
        let floor = 1e-9 * (1.0 + self.e0.abs());
        if de.is_finite() && (de.abs() <= s.max_energy_error * self.scale || de.abs() <= floor) {
            return Ok(());
        }
        Err(Error::Diverged {
            t: x.t,
            message: format!(
                "the energy of this passive scene changed by {de:.3e} J ({:.0} % of the {:.3e} J in \
                 motion, more than max_energy_error = {}): dt = {} s is too large for {:?}; reduce dt \
                 or use dopri5",
                100.0 * de.abs() / self.scale.max(f64::MIN_POSITIVE),
                self.scale,
                s.max_energy_error,
                s.dt,
                s.method
            ),
        })
    }
}

/// Bounded work, before running: steps, control ticks and samples (`check_counts`), and
/// the work of the fixed-step methods: steps × evaluations per step × the model's cost.
pub(super) fn check_work(
    s: &IntegrationSettings,
    model: &Model,
    control: Option<f64>,
    horizon: f64,
) -> Result<()> {
    s.check_counts(horizon, control)?;
    // The answer's evaluations per step, three times over: the error estimate's companion takes
    // two steps of dt/2 per step (estimate.rs).
    let per_step = match s.method {
        Method::SemiImplicitEuler => 3.0,
        Method::Rk4 => 12.0,
        // Adaptive or iterative: counted while running (`advance`).
        Method::Dopri5 | Method::Dop853 | Method::Sdirk2 | Method::Radau5 => return Ok(()),
    };
    let steps = (horizon / s.dt).ceil();
    let work = steps * per_step * crate::limits::evaluation_cost(model);
    if work > s.max_work {
        return Err(Error::WorkLimit {
            what: format!(
                "work units ({steps:e} steps × {per_step} evaluations × {:.3e} per evaluation \
                 of this {}-body model)",
                crate::limits::evaluation_cost(model),
                model.nbodies() - 1
            ),
            estimate: work,
            limit: s.max_work,
            hint: "shorten the horizon, raise dt, or raise integration.max_work".into(),
        });
    }
    Ok(())
}

impl super::run::Predictor {
    /// Refuse, before running, a fixed explicit step beyond the method's stability limit for the
    /// stiffest spring or damper: dt·max(ω, d/m) from k (M⁻¹)_ii, d (M⁻¹)_ii per joint element.
    pub(super) fn check_step_size(
        &mut self,
        q: &[f64],
        v: &[f64],
        s: &IntegrationSettings,
    ) -> Result<()> {
        let Some(limit) = s.method.explicit_stability_limit() else {
            return Ok(());
        };
        let zero = vec![0.0; v.len()];
        forward_kinematics(&self.sys.model, &mut self.sys.data, q, v, &zero);
        let m = crba(&self.sys.model, &mut self.sys.data, q).clone();
        let reg = m.diagonal().amax().max(1e-12) * 1e-12;
        let minv = (m + nalgebra::DMatrix::identity(v.len(), v.len()) * reg)
            .try_inverse()
            .unwrap_or_default();
        let rate = self.forces.max_rate(&self.sys.model, &self.sys.data, &minv);
        if s.dt * rate > limit {
            return Err(Error::StepTooLarge {
                message: format!(
                    "dt = {} s exceeds the {:?} stability limit {:.3e} s for the stiffest force element \
                     (rate {rate:.3e} 1/s); use a smaller dt or method sdirk2",
                    s.dt,
                    s.method,
                    limit / rate
                ),
            });
        }
        Ok(())
    }
}
