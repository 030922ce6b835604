//! One span of a prediction: the integration steps of one lane (the answer or the error
//! estimate's companion) between two control ticks or samples, with drift control, covariance
//! and the work bound after every step.

use super::DriftControl;
use super::IntegrationSettings;
use super::drift::Projector;
use super::estimate::Lane;
use super::integrator::{
    Accel, DOPRI5, Method, RK4, dopri5_error_norm, explicit_step, sdirk2_step,
    semi_implicit_euler_step,
};
use super::run::Predictor;
use crate::applied::applied_generalized_force;
use crate::dynamics::Formulation;
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::system::{DynamicsOptions, System};

/// The right-hand side: held actuator torques + force elements → constrained q̈.
struct Rhs<'a> {
    sys: &'a mut System,
    forces: &'a mut ForceElements,
    tau_act: &'a [f64],
    tau: &'a mut [f64],
    zero: &'a [f64],
    ls: &'a mut Projector,
    evaluations: usize,
    least_squares: usize,
}

impl Accel for Rhs<'_> {
    fn accel(&mut self, t: f64, q: &[f64], v: &[f64], qdd: &mut [f64]) -> Result<()> {
        self.evaluations += 1;
        // Time reaches the constraints through their workspace (`velocity` rows may use t).
        self.sys.cdata.t = t;
        applied_generalized_force(
            self.sys,
            self.forces,
            (t, q, v),
            self.tau_act,
            self.zero,
            self.tau,
        );
        // `formulation: auto` takes the multiplier form here: the same q̈ as the embedded form
        // (tests/propagation_formulations.rs), 1.08–1.7× faster on every bundled scene
        // (docs/performance.md).
        // Least squares (λ = S⁺ r) where stages or drift make redundant rows disagree: the same
        // formula on both sides of any threshold, so q̈ stays smooth for the implicit method.
        let opts = DynamicsOptions {
            formulation: match self.sys.formulation {
                Formulation::Embedded => Formulation::Embedded,
                _ => Formulation::Multipliers,
            },
            allow_inconsistent: true,
        };
        let result = self
            .sys
            .forward_dynamics_with(q, v, self.tau, opts)
            .map(|a| qdd.copy_from_slice(a.as_slice()));
        if result.is_ok() && self.sys.kkt.inconsistency > 1e-7 * self.sys.kkt.b.amax().max(1.0) {
            self.least_squares += 1;
        }
        match result {
            Ok(()) => Ok(()),
            Err(Error::InconsistentConstraints { .. }) => {
                // At a singular configuration the acceleration rows disagree by the drift:
                // satisfy the independent ones (counted in `Trajectory::least_squares_evaluations`).
                self.least_squares += 1;
                self.ls
                    .least_squares_accel(self.sys, q, v, self.tau, qdd)
                    .map(|_| ())
            }
            Err(e) => Err(e),
        }
    }
}

impl Predictor {
    /// Integrate `lane` over `span` = (t0, t1) with the chosen method, controlling drift after
    /// every step. `cap`: None for the answer (the covariance follows it); for the error
    /// estimate's companion, the largest DOPRI5 step it may take (half the answer's largest in the
    /// span, so that it refines even where the span, not the tolerance, limits the step).
    /// `prior` evaluations of the other lane count toward `max_work`. Returns the largest step
    /// taken [s].
    pub(super) fn advance(
        &mut self,
        lane: &mut Lane,
        cap: Option<f64>,
        prior: usize,
        span: (f64, f64),
        s: &IntegrationSettings,
    ) -> Result<f64> {
        let (t0, t1) = span;
        let cost = self.ws.cost;
        let model = &self.model;
        let ws = &mut self.ws;
        let mut rhs = Rhs {
            sys: &mut self.sys,
            forces: &mut self.forces,
            // Each lane under the torque of its own controllers (run.rs, Workspace).
            tau_act: if cap.is_none() {
                &ws.tau_act
            } else {
                &ws.tau_companion
            },
            tau: &mut ws.tau,
            zero: &ws.zero,
            ls: &mut ws.ls,
            evaluations: 0,
            least_squares: 0,
        };
        let Lane {
            q,
            v,
            step,
            proj,
            h,
            steps,
            evaluations,
            least_squares,
        } = lane;
        let (q, v) = (&mut q[..], &mut v[..]);
        let mut cov = match cap {
            None => self.covariance.as_mut(),
            Some(_) => None,
        };
        let cap = cap.unwrap_or(f64::INFINITY);
        let mut largest = 0.0f64;
        // Fixed steps: the span in n equal steps of at most dt, n computed once (issue 13: a
        // step recomputed from the remaining time came out a rounding error short and added
        // one more step).
        let n_fixed = ((t1 - t0) / s.dt * (1.0 - 1e-9)).ceil().max(1.0);
        let h_fixed = (t1 - t0) / n_fixed;
        let mut i = 0.0;
        let mut t = t0;
        let result = (|| -> Result<()> {
            while t < t1 - 1e-12 {
                let dt = if s.method == Method::Dopri5 {
                    h.min(t1 - t).min(cap)
                } else {
                    h_fixed
                };
                if cov.is_some() {
                    ws.qn.copy_from_slice(q);
                    ws.vn.copy_from_slice(v);
                    let (qn, vn) = (&ws.qn, &ws.vn);
                    applied_generalized_force(
                        rhs.sys,
                        rhs.forces,
                        (t, qn, vn),
                        rhs.tau_act,
                        rhs.zero,
                        &mut ws.tau_n,
                    );
                }
                match s.method {
                    Method::SemiImplicitEuler => {
                        semi_implicit_euler_step(&mut rhs, model, t, dt, q, v, step)?
                    }
                    Method::Rk4 => explicit_step(&mut rhs, model, &RK4, t, dt, q, v, step)?,
                    Method::Sdirk2 => sdirk2_step(&mut rhs, model, t, dt, q, v, step)?,
                    Method::Dopri5 => {
                        explicit_step(&mut rhs, model, &DOPRI5, t, dt, q, v, step)?;
                        let norm = dopri5_error_norm(step, v, s);
                        let factor = (0.9 * norm.max(1e-10).powf(-0.2)).clamp(0.2, 5.0);
                        if norm > 1.0 || !norm.is_finite() {
                            step.restore(q, v);
                            *h = dt * factor.min(0.5);
                            if *h < 1e-14 * t1.max(1.0) {
                                let singular = if rhs.least_squares > 0 {
                                    format!(
                                        " at a singular configuration of the constraints (the \
                                         constraint accelerations were inconsistent {} times): \
                                         loosen rtol, or use rk4 with projection",
                                        rhs.least_squares
                                    )
                                } else {
                                    String::new()
                                };
                                return Err(Error::Diverged {
                                    t,
                                    message: format!(
                                        "dopri5 cannot meet rtol = {:e} (step size underflow, \
                                         h = {h:e} s){singular}",
                                        s.rtol
                                    ),
                                });
                            }
                            continue;
                        }
                        // A step shortened to land on t1 does not shrink the next one.
                        *h = if dt < *h {
                            (dt * factor).max(*h)
                        } else {
                            dt * factor
                        };
                    }
                }
                if s.method == Method::Dopri5 {
                    t += dt;
                } else {
                    i += 1.0;
                    t = if i >= n_fixed { t1 } else { t0 + i * h_fixed };
                }
                *steps += 1;
                largest = largest.max(dt);
                // Adaptive and implicit methods take as many steps and evaluations as the
                // problem asks: bounded while running.
                let work = (prior + *evaluations + rhs.evaluations) as f64 * cost;
                if *steps as f64 > s.max_steps || work > s.max_work {
                    return Err(Error::WorkLimit {
                        what: format!("steps ({}) or work units ({work:.3e}) at t = {t} s", *steps),
                        estimate: (*steps as f64).max(work),
                        limit: if *steps as f64 > s.max_steps {
                            s.max_steps
                        } else {
                            s.max_work
                        },
                        hint: "loosen rtol, shorten the horizon, or raise integration.max_steps \
                               / max_work"
                            .into(),
                    });
                }
                if s.drift == DriftControl::Projection {
                    rhs.sys.cdata.t = t;
                    proj.project(rhs.sys, q, v, true)?;
                }
                if let Some(c) = cov.as_mut() {
                    let start = (&ws.qn[..], &ws.vn[..]);
                    c.record_step(rhs.sys, s.method, start, &ws.tau_n, dt, (q, v))?;
                }
                if let Some(bad) = q
                    .iter()
                    .chain(v.iter())
                    .find(|x| !x.is_finite() || x.abs() > 1e12)
                {
                    return Err(Error::Diverged {
                        t,
                        message: format!(
                            "the state left all bounds ({bad:e}); reduce dt or use method sdirk2"
                        ),
                    });
                }
            }
            Ok(())
        })();
        *evaluations += rhs.evaluations;
        *least_squares += rhs.least_squares;
        result.map(|()| largest).map_err(|e| match e {
            Error::Diverged { t: tt, message } if tt.is_nan() => Error::Diverged { t, message },
            e => e,
        })
    }
}

/// An error of the companion run names it: its settings are not the user's.
pub(super) fn companion_error(e: Error) -> Error {
    let what = "in the error estimate's companion run (dt / 2, or dopri5's tolerances / 32)";
    match e {
        Error::Diverged { t, message } => Error::Diverged {
            t,
            message: format!("{what}: {message}"),
        },
        Error::StepTooLarge { message } => Error::StepTooLarge {
            message: format!("{what}: {message}"),
        },
        e => e,
    }
}
