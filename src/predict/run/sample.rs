//! How a prediction's output sample is taken at a state (trajectory.rs says what it holds).

use crate::algorithm::{kinetic_energy, potential_energy};
use crate::applied::constraint_forces_at;
use crate::constraints::ContactLimits;
use crate::error::Result;
use crate::predict::covariance::worker::covariance_rows;
use crate::predict::error_kinds::ByKind;
use crate::predict::predictor::Predictor;
use crate::predict::trajectory::Sample;

impl Predictor {
    /// The output sample at (t, q, v): residuals, energies, λ and the constraint forces when
    /// `forces` (the contacts judged under its limits) — at `forces_at`, the state's
    /// projection onto the constraints, where it is given —, the covariance when one is
    /// propagated inline and `covariance`; `err` the error estimate.
    pub(in crate::predict) fn sample(
        &mut self,
        t: f64,
        (q, v): (&[f64], &[f64]),
        forces_at: Option<(&[f64], &[f64])>,
        err: Option<ByKind>,
        (forces, covariance): (Option<&ContactLimits>, bool),
    ) -> Result<Sample> {
        let sys = &mut self.sys;
        let at = match forces {
            Some(_) if !sys.constraints().is_empty() => Some(constraint_forces_at(
                sys,
                &mut self.forces,
                (
                    t,
                    forces_at.map_or(q, |s| s.0),
                    forces_at.map_or(v, |s| s.1),
                ),
                &self.ws.tau_act,
            )?),
            _ => None,
        };
        // Judged before the residuals move the kinematics off the state λ was solved at.
        let contacts = match (&at, forces) {
            (Some(f), Some(limits)) => {
                // Reads λ and the tyres only: the prediction is the same with or without it.
                let (model, data) = (sys.model(), sys.data());
                (self.contact_judge).judge(&f.lambda, limits, model, data, &self.forces)
            }
            _ => None,
        };
        let (position_residual, velocity_residual) = sys.residuals(t, q, v);
        let (model, data) = (sys.model(), sys.data());
        let ke = kinetic_energy(model, data);
        let pe = potential_energy(model, data) + self.forces.potential_energy(model, data, q);
        let (contacts, lambda, forces, generalized_force, rank_deficiency) = match (at, forces) {
            (Some(f), Some(_)) => (
                contacts,
                Some(f.lambda),
                Some(f.forces),
                Some(f.generalized_force),
                Some(f.rank_deficiency),
            ),
            _ => (None, None, None, None, None),
        };
        let energies = [
            ke,
            pe,
            position_residual,
            velocity_residual,
            err.map_or(0.0, |e| e.largest()),
        ];
        if let Some((what, x)) = [
            ("q", q),
            ("v", v),
            ("energies, residuals and error estimate", &energies[..]),
        ]
        .into_iter()
        .find(|(_, x)| x.iter().any(|y| !y.is_finite()))
        {
            crate::error::check_output(
                &format!("sample at t = {t} s: {what}"),
                x,
                "the state overflows the arithmetic; see the input ranges in README.md",
            )?;
        }
        // (With the covariance on its worker, the rows are attached when the run ends.)
        let covariance = match &self.covariance {
            Some(c) if covariance => Some(covariance_rows(&c.reading.p, t)?),
            _ => None,
        };
        Ok(Sample {
            t,
            q: q.to_vec(),
            v: v.to_vec(),
            actuator_torque: self.ws.tau_act.clone(),
            lambda,
            forces,
            generalized_force,
            contacts,
            rank_deficiency,
            position_residual,
            velocity_residual,
            kinetic_energy: ke,
            potential_energy: pe,
            error_estimate: err.map(|e| e.largest()),
            error_estimate_by_kind: err,
            covariance,
            saturated_s: 0.0,
        })
    }
}
