//! A prediction's output sample at one state: residuals, energies, forces on request, the
//! propagated covariance when there is one.

use super::covariance_worker::covariance_rows;
use super::run::Predictor;
use super::trajectory::Sample;
use crate::algorithm::{kinetic_energy, potential_energy};
use crate::applied::constraint_forces_at;
use crate::error::Result;

impl Predictor {
    pub(super) fn sample(
        &mut self,
        t: f64,
        q: &[f64],
        v: &[f64],
        err: Option<f64>,
        forces: bool,
    ) -> Result<Sample> {
        let sys = &mut self.sys;
        let at = match forces {
            true if !sys.constraints.is_empty() => Some(constraint_forces_at(
                sys,
                &mut self.forces,
                (t, q, v),
                &self.ws.tau_act,
            )?),
            _ => None,
        };
        // Time reaches the constraints through their workspace (`velocity` rows may use t).
        sys.cdata.t = t;
        sys.constraints
            .evaluate(&sys.model, &mut sys.data, &mut sys.cdata, q, v);
        let cd = &sys.cdata;
        let position_residual = (0..sys.constraints.nrows)
            .filter(|&k| cd.holonomic[k])
            .map(|k| cd.phi[k].abs())
            .fold(0.0, f64::max);
        let velocity_residual = cd.jv.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let ke = kinetic_energy(&sys.model, &sys.data);
        let pe = potential_energy(&sys.model, &sys.data)
            + self.forces.potential_energy(&sys.model, &sys.data, q);
        let (lambda, forces, generalized_force, rank_deficiency) = match at {
            Some(f) => (
                Some(f.lambda),
                Some(f.forces),
                Some(f.generalized_force),
                Some(f.rank_deficiency),
            ),
            None => (None, None, None, None),
        };
        let energies = [
            ke,
            pe,
            position_residual,
            velocity_residual,
            err.unwrap_or(0.0),
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
            Some(c) => Some(covariance_rows(&c.p, t)?),
            None => None,
        };
        Ok(Sample {
            t,
            q: q.to_vec(),
            v: v.to_vec(),
            actuator_torque: self.ws.tau_act.clone(),
            lambda,
            forces,
            generalized_force,
            rank_deficiency,
            position_residual,
            velocity_residual,
            kinetic_energy: ke,
            potential_energy: pe,
            error_estimate: err,
            covariance,
        })
    }
}
