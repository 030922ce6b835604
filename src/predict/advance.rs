//! One span of a prediction: the integration steps of one lane (the answer or the error
//! estimate's companion) between two control ticks or samples, with drift control, covariance
//! and the work bound after every step.

use super::DriftControl;
use super::IntegrationSettings;
use super::drift::DriftProjector;
use super::estimate::Lane;
use super::predictor::Predictor;
use crate::actuators::Actuators;
use crate::applied::applied_generalized_force;
use crate::derivatives::DerivativeData;
use crate::dynamics::disagree_beyond_rounding;
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::model::Model;
use crate::predict::covariance::linearize::dynamics_derivatives;
use crate::predict::covariance::worker::CovarianceFeed;
use crate::predict::integrators::radau::radau5_step;
use crate::predict::integrators::ros2::ros2_step;
use crate::predict::integrators::sdirk2::sdirk2_step;
use crate::predict::integrators::{
    Accel, DOP853, DOPRI5, JacobianScratch, Method, RK4, accel_jacobian_fd, dop853_error_norm,
    dopri5_error_norm, explicit_step, semi_implicit_euler_step, stage,
};
use crate::system::{DynamicsOptions, System};
use nalgebra::DMatrix;

/// Buffers of the right-hand side's Jacobian: the analytic derivatives of the dynamics and the
/// force elements' generalized force differenced (kinematics only).
#[derive(Clone, Debug, Default)]
pub(super) struct JacobianWork {
    /// None: finite differences of the whole right-hand side.
    dd: Option<DerivativeData>,
    tau_p: Vec<f64>,
    tau_m: Vec<f64>,
    dtau: Vec<f64>,
    dx: Vec<f64>,
    qs: Vec<f64>,
    vs: Vec<f64>,
}

impl JacobianWork {
    pub(super) fn new(sys: &System) -> Self {
        let (nq, nv) = (sys.model.nq, sys.model.nv);
        Self {
            dd: Some(DerivativeData::new(&sys.model, sys.constraints.nrows)),
            tau_p: vec![0.0; nv],
            tau_m: vec![0.0; nv],
            dtau: vec![0.0; nv],
            dx: vec![0.0; 2 * nv],
            qs: vec![0.0; nq],
            vs: vec![0.0; nv],
        }
    }
}

/// The right-hand side: actuator torques (held, or continuous controllers evaluated at the
/// stage) + force elements → constrained q̈.
struct Rhs<'a> {
    sys: &'a mut System,
    forces: &'a mut ForceElements,
    tau_act: &'a [f64],
    /// Continuous controllers (`hold: continuous`), evaluated into `tau_ctl` at every stage
    /// instead of `tau_act`.
    control: Option<&'a Actuators>,
    tau_ctl: &'a mut [f64],
    tau: &'a mut [f64],
    zero: &'a [f64],
    ls: &'a mut DriftProjector,
    jw: &'a mut JacobianWork,
    rows: RowsAt<'a>,
    probe: Probe<'a>,
    evaluations: usize,
    least_squares: usize,
}

/// Where the system's kinematics and constraint rows were last evaluated by the drift
/// projection, when it left the state there: the next step's first stage, at that same
/// (t, q, v), reuses them (`DynamicsOptions::rows_evaluated`) instead of a second pass.
struct RowsAt<'a> {
    t: Option<f64>,
    q: &'a mut [f64],
    v: &'a mut [f64],
}

/// A q̈ the run probed at (t, q, v) (`Predictor::probe_accel`), for the first evaluation there.
struct Probe<'a> {
    t: &'a mut Option<f64>,
    q: &'a [f64],
    v: &'a [f64],
    qdd: &'a [f64],
}

impl Probe<'_> {
    /// True once, for the probed state (bitwise): its q̈ is copied into `qdd`.
    fn take(&mut self, t: f64, q: &[f64], v: &[f64], qdd: &mut [f64]) -> bool {
        let hit = self.t.take() == Some(t) && self.q == q && self.v == v;
        if hit {
            qdd.copy_from_slice(self.qdd);
        }
        hit
    }
}

impl RowsAt<'_> {
    fn mark(&mut self, t: f64, q: &[f64], v: &[f64]) {
        self.t = Some(t);
        self.q.copy_from_slice(q);
        self.v.copy_from_slice(v);
    }

    /// True once, for the marked state (bitwise the same q and v: anything else evaluates).
    fn take(&mut self, t: f64, q: &[f64], v: &[f64]) -> bool {
        self.t.take() == Some(t) && *self.q == *q && *self.v == *v
    }
}

impl Rhs<'_> {
    /// τ at (t, q, v) into `tau`; time reaches the constraints through their workspace
    /// (`velocity` rows may use t).
    fn apply(&mut self, t: f64, q: &[f64], v: &[f64]) {
        self.sys.cdata.t = t;
        let tau_act: &[f64] = match self.control {
            Some(a) => {
                a.continuous_torque(t, q, v, self.tau_ctl);
                self.tau_ctl
            }
            None => self.tau_act,
        };
        applied_generalized_force(
            self.sys,
            self.forces,
            (t, q, v),
            tau_act,
            self.zero,
            self.tau,
        );
    }
}

impl Accel for Rhs<'_> {
    fn accel(&mut self, t: f64, q: &[f64], v: &[f64], qdd: &mut [f64]) -> Result<()> {
        if self.probe.take(t, q, v, qdd) {
            return Ok(());
        }
        self.evaluations += 1;
        let rows_evaluated = self.rows.take(t, q, v);
        self.apply(t, q, v);
        // `formulation: auto` takes the multiplier form here: the same q̈ as the embedded form
        // (tests/propagation_formulations.rs), 1.08–1.7× faster on every bundled scene
        // (docs/performance.md). Least squares (λ = S⁺ r) where stages or drift make redundant
        // rows disagree (`DynamicsOptions::stage`).
        let opts = DynamicsOptions {
            rows_evaluated,
            ..DynamicsOptions::stage(self.sys.formulation)
        };
        let result = self
            .sys
            .forward_dynamics_with(q, v, self.tau, opts)
            .map(|a| qdd.copy_from_slice(a.as_slice()));
        let kkt = &self.sys.kkt;
        if result.is_ok() && disagree_beyond_rounding(kkt.inconsistency, kkt.b.amax()) {
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

    /// Analytic: the derivatives of the constrained (or free) forward dynamics at the applied τ,
    /// plus ∂q̈/∂τ · ∂τ/∂(q, v) of the continuous controllers and of the force elements — their
    /// joint spring-dampers in closed form, any other element's generalized force by central
    /// differences (kinematics only: a point spring's geometric stiffness included). Falls back to
    /// differences of the whole right-hand side where the derivatives are not available (a kind
    /// without them, or a singular configuration).
    fn accel_jacobian(
        &mut self,
        model: &Model,
        (t, q, v): (f64, &[f64], &[f64]),
        qdd: &[f64],
        jac: &mut DMatrix<f64>,
        scratch: &mut JacobianScratch,
    ) -> Result<bool> {
        let nv = v.len();
        // The derivatives (or differences) evaluate at other states: nothing to reuse after.
        self.rows.t = None;
        self.apply(t, q, v);
        let Some(dd) = self.jw.dd.as_mut() else {
            accel_jacobian_fd(self, model, (t, q, v), qdd, jac, scratch)?;
            return Ok(false);
        };
        let analytic = dynamics_derivatives(self.sys, dd, q, v, self.tau);
        if analytic.is_err() {
            accel_jacobian_fd(self, model, (t, q, v), qdd, jac, scratch)?;
            return Ok(false);
        }
        for r in 0..nv {
            for c in 0..nv {
                jac[(nv + r, c)] = dd.dqdd_dq[(r, c)];
                jac[(nv + r, nv + c)] = dd.dqdd_dv[(r, c)];
            }
        }
        // A joint force −k q − d v + rate·t (a continuous controller, a joint spring-damper)
        // moves q̈ by ∂q̈/∂τ_j (−k, −d) on its joint's columns (1-DOF: its tangent column is its
        // v index), and ∂q̈/∂t by ∂q̈/∂τ_j rate.
        let dqdd_dt = &mut scratch.dqdd_dt;
        dqdd_dt.iter_mut().for_each(|x| *x = 0.0);
        let mut joint_feedback = |iv: usize, k: f64, d: f64, rate: f64| {
            for r in 0..nv {
                let g = dd.dqdd_dtau[(r, iv)];
                jac[(nv + r, iv)] -= g * k;
                jac[(nv + r, nv + iv)] -= g * d;
                dqdd_dt[r] += g * rate;
            }
        };
        if let Some(a) = self.control {
            a.continuous_feedback(t, q, v, |fb| joint_feedback(fb.iv, fb.k, fb.d, fb.rate));
        }
        if self.forces.depends_on_state_by_joints_only() {
            for &(_, iv, k, d, _) in self.forces.joint_spring_dampers() {
                joint_feedback(iv, k, d, 0.0);
            }
            return Ok(true);
        }
        let jw = &mut *self.jw;
        let dd = jw.dd.as_ref().expect("checked above");
        for col in 0..2 * nv {
            let eps = 1e-6
                * if col < nv {
                    1.0
                } else {
                    v[col - nv].abs().max(1.0)
                };
            for (sign, out) in [(1.0, &mut jw.tau_p), (-1.0, &mut jw.tau_m)] {
                jw.dx.iter_mut().for_each(|x| *x = 0.0);
                jw.dx[col] = sign * eps;
                stage(model, q, v, &jw.dx, &mut jw.qs, &mut jw.vs);
                // The held torque: the controllers' share is in the feedback above.
                applied_generalized_force(
                    self.sys,
                    self.forces,
                    (t, &jw.qs, &jw.vs),
                    self.tau_act,
                    self.zero,
                    out,
                );
            }
            for j in 0..nv {
                jw.dtau[j] = (jw.tau_p[j] - jw.tau_m[j]) / (2.0 * eps);
            }
            for r in 0..nv {
                jac[(nv + r, col)] += (0..nv)
                    .map(|j| dd.dqdd_dtau[(r, j)] * jw.dtau[j])
                    .sum::<f64>();
            }
        }
        Ok(true)
    }
}

impl Predictor {
    /// q̈ at the lane's state at t into `ws.probe_qdd` (one evaluation, counted in the lane's):
    /// where a frozen controller's torque is heading (`Actuators::saturation_exit`). The
    /// answer's next step starts there and takes it as its first evaluation.
    pub(super) fn probe_accel(&mut self, lane: &mut Lane, t: f64) -> Result<()> {
        let actuators = &self.actuators;
        let ws = &mut self.ws;
        ws.probe_t = None;
        let mut rhs = Rhs {
            sys: &mut self.sys,
            forces: &mut self.forces,
            tau_act: &ws.tau_act,
            control: actuators.is_continuous().then_some(actuators),
            tau_ctl: &mut ws.tau_ctl,
            tau: &mut ws.tau,
            zero: &ws.zero,
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
        let actuators = &self.actuators;
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
            control: actuators.is_continuous().then_some(actuators),
            tau_ctl: &mut ws.tau_ctl,
            tau: &mut ws.tau,
            zero: &ws.zero,
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
                // Adaptive methods: (accepted, next step); a rejected step left (q, v) as they were.
                let adapt = match s.method {
                    Method::SemiImplicitEuler => {
                        semi_implicit_euler_step(&mut rhs, model, t, dt, q, v, step)?;
                        None
                    }
                    Method::Rk4 => {
                        explicit_step(&mut rhs, model, &RK4, t, dt, q, v, step)?;
                        None
                    }
                    Method::Sdirk2 => {
                        sdirk2_step(&mut rhs, model, t, dt, q, v, step)?;
                        None
                    }
                    Method::Ros2 => {
                        ros2_step(&mut rhs, model, t, dt, q, v, step)?;
                        None
                    }
                    Method::Dopri5 => {
                        explicit_step(&mut rhs, model, &DOPRI5, t, dt, q, v, step)?;
                        let norm = dopri5_error_norm(step, v, s);
                        let factor = (0.9 * norm.max(1e-10).powf(-0.2)).clamp(0.2, 5.0);
                        if norm > 1.0 || !norm.is_finite() {
                            step.restore(q, v);
                            Some((false, dt * factor.min(0.5)))
                        } else {
                            Some((true, dt * factor))
                        }
                    }
                    Method::Dop853 => {
                        explicit_step(&mut rhs, model, &DOP853, t, dt, q, v, step)?;
                        let norm = dop853_error_norm(step, v, s);
                        let factor = (0.9 * norm.max(1e-12).powf(-1.0 / 8.0)).clamp(0.2, 10.0);
                        if norm > 1.0 || !norm.is_finite() {
                            step.restore(q, v);
                            Some((false, dt * factor.min(0.5)))
                        } else {
                            Some((true, dt * factor))
                        }
                    }
                    Method::Radau5 => {
                        let o = radau5_step(&mut rhs, model, t, dt, q, v, radau, (s.rtol, s.atol))?;
                        Some((o.accepted, o.h_next))
                    }
                };
                if let Some((accepted, h_next)) = adapt {
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
                    rhs.sys.cdata.t = t;
                    proj.project(rhs.sys, q, v, true)?;
                    // The covariance's linearization below evaluates elsewhere.
                    if proj.rows_current && cov.is_none() {
                        rhs.rows.mark(t, q, v);
                    }
                }
                if let Some(c) = cov.as_mut() {
                    let start = (&ws.qn[..], &ws.vn[..]);
                    let feedback = actuators.feedback();
                    // ROS2's step brings its F and its increment (integrators/ros2.rs).
                    let own = (s.method == Method::Ros2).then_some((&step.jac, &step.dx[..]));
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
