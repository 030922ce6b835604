//! One span of a prediction: the integration steps of one lane (the answer or the error
//! estimate's companion) between two control ticks or samples, with drift control, covariance
//! and the work bound after every step.

use super::rhs::{Probe, Rhs, RowsAt};
use crate::error::{Error, Result};
use crate::predict::DriftControl;
use crate::predict::IntegrationSettings;
use crate::predict::covariance::worker::CovarianceFeed;
use crate::predict::estimate::Lane;
use crate::predict::integrators::{Accel, StepOutcome};
use crate::predict::predictor::Predictor;

impl Predictor {
    /// q̈ at the lane's state at t into `ws.probe_qdd` (one evaluation, counted in the lane's):
    /// where a frozen controller's torque is heading (`Actuators::saturation_exit`). The
    /// answer's next step starts there and takes it as its first evaluation.
    pub(in crate::predict) fn probe_accel(&mut self, lane: &mut Lane, t: f64) -> Result<()> {
        let actuators = &self.actuators;
        let ws = &mut self.ws;
        ws.probe_t = None;
        let mut rhs = Rhs {
            sys: &mut self.sys,
            gains: ws.gains,
            forces: &mut self.forces,
            tau_act: &ws.tau_act,
            control: actuators.is_continuous().then_some(actuators),
            tau_ctl: &mut ws.tau_ctl,
            tau: &mut ws.tau,
            ls: &mut ws.ls,
            jw: &mut ws.jw,
            rows: RowsAt {
                t: None,
                q: &mut ws.rows_q,
                v: &mut ws.rows_v,
            },
            probe: Probe {
                t: &mut None,
                q: &[],
                v: &[],
                qdd: &[],
            },
            invariant: self.config.invariant.as_ref(),
            evaluations: 0,
            least_squares: 0,
        };
        let result = rhs.accel(t, &lane.q, &lane.v, &mut ws.probe_qdd);
        lane.evaluations += rhs.evaluations;
        lane.least_squares += rhs.least_squares;
        if result.is_ok() {
            ws.probe_t = Some(t);
            ws.probe_q.copy_from_slice(&lane.q);
            ws.probe_v.copy_from_slice(&lane.v);
        }
        result
    }

    /// Integrate `lane` over `span` = (t0, t1) with the chosen method, controlling drift after
    /// every step. `cap`: None for the answer (the covariance follows it); for the error
    /// estimate's companion, the largest DOPRI5 step it may take (half the answer's largest in the
    /// span, so that it refines even where the span, not the tolerance, limits the step).
    /// `prior` evaluations of the other lane count toward `max_work`. Returns the largest step
    /// taken [s].
    pub(in crate::predict) fn advance(
        &mut self,
        lane: &mut Lane,
        cap: Option<f64>,
        prior: usize,
        span: (f64, f64),
        s: &IntegrationSettings,
    ) -> Result<f64> {
        let (t0, t1) = span;
        let cost = (self.ws.cost).per_evaluation(s.method.integrator().is_implicit());
        let model = &self.model;
        let actuators = &self.actuators;
        let ws = &mut self.ws;
        let mut rhs = Rhs {
            sys: &mut self.sys,
            gains: ws.gains,
            forces: &mut self.forces,
            // Each lane under the torque of its own controllers (run/mod.rs, Workspace).
            tau_act: if cap.is_none() {
                &ws.tau_act
            } else {
                &ws.tau_companion
            },
            control: actuators.is_continuous().then_some(actuators),
            tau_ctl: &mut ws.tau_ctl,
            tau: &mut ws.tau,
            ls: &mut ws.ls,
            jw: &mut ws.jw,
            rows: RowsAt {
                t: None,
                q: &mut ws.rows_q,
                v: &mut ws.rows_v,
            },
            // The probe was the answer's state: the companion evaluates its own.
            probe: Probe {
                t: if cap.is_none() {
                    &mut ws.probe_t
                } else {
                    &mut None
                },
                q: &ws.probe_q,
                v: &ws.probe_v,
                qdd: &ws.probe_qdd,
            },
            invariant: self.config.invariant.as_ref(),
            evaluations: 0,
            least_squares: 0,
        };
        let Lane {
            q,
            v,
            step,
            radau,
            proj,
            h,
            steps,
            evaluations,
            least_squares,
        } = lane;
        let (q, v) = (&mut q[..], &mut v[..]);
        let mut cov = match cap {
            None => (self.covariance.as_mut().map(CovarianceFeed::Inline))
                .or_else(|| ws.pipe.get_mut().map(CovarianceFeed::Worker)),
            Some(_) => None,
        };
        let cap = cap.unwrap_or(f64::INFINITY);
        let mut largest = 0.0f64;
        // Fixed steps: the span in n equal steps of at most dt, n computed once (a step
        // recomputed from the remaining time can come out a rounding error short and add one
        // more step).
        let n_fixed = ((t1 - t0) / s.dt * (1.0 - 1e-9)).ceil().max(1.0);
        let h_fixed = (t1 - t0) / n_fixed;
        let mut i = 0.0;
        let mut t = t0;
        // SDIRK2 keeps its own F while Newton converges; ROS2's is refreshed by run.rs.
        let result = (|| -> Result<()> {
            while t < t1 - 1e-12 {
                let dt = if s.method.is_adaptive() {
                    h.min(t1 - t).min(cap)
                } else {
                    h_fixed
                };
                if cov.is_some() {
                    ws.qn.copy_from_slice(q);
                    ws.vn.copy_from_slice(v);
                    let (qn, vn) = (&ws.qn, &ws.vn);
                    rhs.apply(t, qn, vn);
                    ws.tau_n.copy_from_slice(rhs.tau);
                }
                // Adaptive methods: accepted or not, and the next step; a rejected step left
                // (q, v) as they were.
                let adapt = s
                    .method
                    .step(&mut rhs, model, (t, dt), q, v, step, radau, s)?;
                if let Some(StepOutcome { accepted, h_next }) = adapt {
                    if !accepted {
                        *h = h_next;
                        if *h < 1e-14 * t1.max(1.0) {
                            return Err(underflow(s, *h, rhs.least_squares));
                        }
                        continue;
                    }
                    // A step shortened to land on t1 does not shrink the next one.
                    *h = if dt < *h { h_next.max(*h) } else { h_next };
                }
                if s.method.is_adaptive() {
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
                    proj.project(rhs.sys, t, q, v, true, rhs.invariant)?;
                    // The covariance's linearization below evaluates elsewhere.
                    if proj.rows_current && cov.is_none() {
                        rhs.rows.mark(t, q, v);
                    }
                }
                if let Some(c) = cov.as_mut() {
                    let start = (&ws.qn[..], &ws.vn[..]);
                    let feedback = actuators.feedback();
                    // A W-method's step brings its F and its increment (integrators/ros2.rs).
                    let own =
                        (s.method.integrator().is_w_method()).then_some((&step.jac, &step.dx[..]));
                    c.record_step(
                        rhs.sys,
                        s.method,
                        start,
                        &ws.tau_n,
                        feedback,
                        own,
                        dt,
                        (t, (q, v)),
                    )?;
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

/// An adaptive method that cannot meet its tolerance: the step underflowed.
fn underflow(s: &IntegrationSettings, h: f64, least_squares: usize) -> Error {
    let singular = if least_squares > 0 {
        format!(
            " at a singular configuration of the constraints (the constraint accelerations were \
             inconsistent {least_squares} times): loosen rtol, or use rk4 with projection"
        )
    } else {
        String::new()
    };
    Error::Diverged {
        t: f64::NAN,
        message: format!(
            "{} cannot meet rtol = {:e} (step size underflow, h = {h:e} s){singular}",
            s.method.name(),
            s.rtol
        ),
    }
}

/// An error of the companion run names it: its settings are not the user's.
pub(in crate::predict) fn companion_error(e: Error) -> Error {
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
