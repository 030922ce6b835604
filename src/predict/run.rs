//! The prediction loop: control ticks, integration steps, drift control, samples.

use super::covariance::{CovariancePropagator, UncertaintySpec};
use super::drift::Projector;
use super::guard::{EnergyGuard, check_work};
use super::integrator::{
    Accel, DOPRI5, Method, RK4, StepWorkspace, dopri5_error_norm, explicit_step, sdirk2_step,
    semi_implicit_euler_step,
};
use super::trajectory::{PredictOptions, Trajectory};
use super::{DriftControl, IntegrationSettings};
use crate::actuators::{Actuators, Command};
use crate::applied::applied_generalized_force;
use crate::dynamics::{Baumgarte, Formulation};
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::model::Model;
use crate::scene::Scene;
use crate::system::{DynamicsOptions, System};
use nalgebra::DMatrix;
use std::time::Instant;

/// Buffers of a run, sized once per model (the stepping loop allocates nothing).
#[derive(Clone, Debug, Default)]
pub(super) struct Workspace {
    step: StepWorkspace,
    proj: Projector,
    /// Least-squares constrained accelerations at singular configurations.
    ls: Projector,
    tau: Vec<f64>,
    pub(super) tau_act: Vec<f64>,
    zero: Vec<f64>,
    /// The state and applied force at the start of a step (covariance propagation).
    qn: Vec<f64>,
    vn: Vec<f64>,
    tau_n: Vec<f64>,
    /// Work units of one dynamics evaluation (`limits::evaluation_cost`).
    cost: f64,
}

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

/// Scene-configured predictor (model, constraints, force elements, actuators, integration).
#[derive(Clone, Debug)]
pub struct Predictor {
    /// Model, constraints and dynamics workspaces.
    pub sys: System,
    /// The scene's force elements.
    pub forces: ForceElements,
    /// The scene's actuators with their controller state.
    pub actuators: Actuators,
    /// Integration settings (`integration:` of the scene).
    pub settings: IntegrationSettings,
    /// Record λ and the constraint forces in every sample of [`Predictor::predict`] (a setting
    /// of the predictor; [`Predictor::predict_with`] takes it per call instead).
    pub want_forces: bool,
    /// `uncertainty:` of the scene (process noise of the covariance).
    pub uncertainty: UncertaintySpec,
    /// Start covariance of the next predictions (2nv × 2nv, [δq; δv]); None: no covariance.
    pub start_covariance: Option<DMatrix<f64>>,
    pub(super) covariance: Option<CovariancePropagator>,
    pub(super) model: Model,
    pub(super) ws: Workspace,
}

impl Predictor {
    /// Build from a loaded scene: system, `forces:`, `actuators:` and `integration:`.
    pub fn from_scene(scene: &Scene) -> Result<Self> {
        let sys = System::from_scene(scene)?;
        let forces = ForceElements::new(&sys.model, &scene.file.forces)?;
        let actuators = Actuators::new(&sys.model, &scene.file.actuators)?;
        let mut p = Self::new(sys, forces, actuators, scene.file.integration.clone())?;
        p.uncertainty = scene.file.uncertainty.clone();
        Ok(p)
    }

    /// Build from its parts, validating the integration settings.
    pub fn new(
        sys: System,
        forces: ForceElements,
        actuators: Actuators,
        settings: IntegrationSettings,
    ) -> Result<Self> {
        settings.validate()?;
        let model = sys.model.clone();
        let (nq, nv) = (model.nq, model.nv);
        let ws = Workspace {
            step: StepWorkspace::new(nq, nv),
            proj: Projector::new(&sys),
            ls: Projector::new(&sys),
            tau: vec![0.0; nv],
            tau_act: vec![0.0; nv],
            zero: vec![0.0; nv],
            qn: vec![0.0; nq],
            vn: vec![0.0; nv],
            tau_n: vec![0.0; nv],
            cost: crate::limits::evaluation_cost(&model),
        };
        Ok(Self {
            sys,
            forces,
            actuators,
            settings,
            want_forces: false,
            uncertainty: UncertaintySpec::default(),
            start_covariance: None,
            covariance: None,
            model,
            ws,
        })
    }

    /// Propagate from (q0, v0) over `horizon` [s] following `commands` ((start time [s], command),
    /// sorted; the last one started is active), with forces in the samples if `want_forces`.
    pub fn predict(
        &mut self,
        q0: &[f64],
        v0: &[f64],
        commands: &[(f64, Command)],
        horizon: f64,
    ) -> Result<Trajectory> {
        let opts = PredictOptions {
            forces: self.want_forces,
        };
        self.predict_with(q0, v0, commands, horizon, opts)
    }

    /// [`Predictor::predict`] with the options of this one call.
    pub fn predict_with(
        &mut self,
        q0: &[f64],
        v0: &[f64],
        commands: &[(f64, Command)],
        horizon: f64,
        opts: PredictOptions,
    ) -> Result<Trajectory> {
        let start = Instant::now();
        crate::limits::check_input_state(&self.model, q0, v0, &self.ws.zero)?;
        if !(horizon.is_finite() && horizon >= 0.0) {
            return Err(Error::Invalid(format!(
                "horizon = {horizon} s must be finite and ≥ 0"
            )));
        }
        let control = (!self.actuators.is_empty()).then_some(self.actuators.control_period);
        check_work(&self.settings, &self.model, control, horizon)?;
        for (t, c) in commands {
            crate::error::check_finite("command time", &[*t])?;
            self.actuators.check_command(c)?;
        }
        let s = self.settings.clone();
        let saved_gains = self.sys.baumgarte;
        if s.drift == DriftControl::Baumgarte && self.sys.baumgarte == Baumgarte::default() {
            self.sys.baumgarte = Baumgarte::from_time_constant(s.baumgarte_steps * s.dt);
        }
        let result = self.run(q0, v0, commands, horizon, &s, opts);
        self.sys.baumgarte = saved_gains;
        let mut traj = result?;
        traj.run_time_s = start.elapsed().as_secs_f64();
        Ok(traj)
    }

    fn run(
        &mut self,
        q0: &[f64],
        v0: &[f64],
        commands: &[(f64, Command)],
        horizon: f64,
        s: &IntegrationSettings,
        opts: PredictOptions,
    ) -> Result<Trajectory> {
        let (mut q, mut v) = (q0.to_vec(), v0.to_vec());
        self.model.normalize(&mut q);
        self.check_step_size(&q, &v, s)?;
        self.actuators.reset();
        self.ws.step.invalidate();
        self.ws.tau_act.iter_mut().for_each(|x| *x = 0.0);
        self.covariance = match &self.start_covariance {
            Some(p0) => Some(CovariancePropagator::start(
                &mut self.sys,
                &self.uncertainty,
                p0,
                &q,
                &v,
            )?),
            None => None,
        };
        let period = if self.actuators.is_empty() {
            s.sample_period
        } else {
            self.actuators.control_period.min(s.sample_period)
        };
        let mut traj = Trajectory {
            q_names: self.model.q_names.clone(),
            v_names: self.model.v_names.clone(),
            method: s.method,
            samples: vec![],
            steps: 0,
            evaluations: 0,
            least_squares_evaluations: 0,
            run_time_s: 0.0,
        };
        let mut err_acc = if s.method == Method::Dopri5 {
            0.0
        } else {
            f64::NAN
        };
        let mut h = s.dt;
        // The first control tick comes before the first sample, so that every sample's forces
        // include the actuator torque held over the interval that ends (or, at t = 0, starts) there.
        let command_at = |t: f64| {
            commands
                .iter()
                .rev()
                .find(|(ts, _)| *ts <= t + 1e-12)
                .map(|(_, c)| c.clone())
                .unwrap_or_default()
        };
        if !self.actuators.is_empty() && horizon > 0.0 {
            self.actuators.update(
                &command_at(0.0),
                &q,
                &v,
                period.min(horizon),
                &mut self.ws.tau_act,
            );
        }
        let first = self.sample(0.0, &q, &v, err_acc, opts.forces)?;
        let springs = self
            .forces
            .potential_energy(&self.sys.model, &self.sys.data, &q);
        let mut guard = EnergyGuard::new(&first, springs, self.energy_guard_applies(s));
        traj.samples.push(first);
        let (mut t, mut k) = (0.0, 0usize);
        let mut next_sample = s.sample_period;
        while t < horizon - 1e-12 {
            k += 1;
            let t_end = (k as f64 * period).min(horizon);
            if !self.actuators.is_empty() && k > 1 {
                self.actuators
                    .update(&command_at(t), &q, &v, t_end - t, &mut self.ws.tau_act);
            }
            self.advance(
                &mut q,
                &mut v,
                (t, t_end),
                &mut h,
                &mut err_acc,
                &mut traj,
                s,
            )?;
            t = t_end;
            if t >= next_sample - 1e-9 || t >= horizon - 1e-12 {
                let sample = self.sample(t, &q, &v, err_acc, opts.forces)?;
                let springs = self
                    .forces
                    .potential_energy(&self.sys.model, &self.sys.data, &q);
                guard.check(&sample, springs, traj.steps, s)?;
                traj.samples.push(sample);
                while next_sample <= t + 1e-9 {
                    next_sample += s.sample_period;
                }
            }
        }
        Ok(traj)
    }

    /// The energy check runs for passive, conservative scenes stepped by a fixed explicit method.
    fn energy_guard_applies(&self, s: &IntegrationSettings) -> bool {
        matches!(s.method, Method::SemiImplicitEuler | Method::Rk4)
            && self.actuators.is_empty()
            && self.forces.is_conservative()
            && s.max_energy_error.is_finite()
    }

    /// Integrate over `span` = (t0, t1) with the chosen method, controlling drift after every step.
    #[allow(clippy::too_many_arguments)]
    fn advance(
        &mut self,
        q: &mut [f64],
        v: &mut [f64],
        span: (f64, f64),
        h: &mut f64,
        err_acc: &mut f64,
        traj: &mut Trajectory,
        s: &IntegrationSettings,
    ) -> Result<()> {
        let (t0, t1) = span;
        let cost = self.ws.cost;
        let model = &self.model;
        let ws = &mut self.ws;
        let mut rhs = Rhs {
            sys: &mut self.sys,
            forces: &mut self.forces,
            tau_act: &ws.tau_act,
            tau: &mut ws.tau,
            zero: &ws.zero,
            ls: &mut ws.ls,
            evaluations: 0,
            least_squares: 0,
        };
        let step = &mut ws.step;
        let cov = &mut self.covariance;
        let mut t = t0;
        let result = (|| -> Result<()> {
            while t < t1 - 1e-12 {
                let dt = if s.method == Method::Dopri5 {
                    h.min(t1 - t)
                } else {
                    (t1 - t) / ((t1 - t) / s.dt - 1e-9).ceil().max(1.0)
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
                        *err_acc += step.err[..v.len()]
                            .iter()
                            .fold(0.0f64, |m, x| m.max(x.abs()));
                        // A step shortened to land on t1 does not shrink the next one.
                        *h = if dt < *h {
                            (dt * factor).max(*h)
                        } else {
                            dt * factor
                        };
                    }
                }
                t += dt;
                traj.steps += 1;
                // Adaptive and implicit methods take as many steps and evaluations as the
                // problem asks: bounded while running.
                let work = (traj.evaluations + rhs.evaluations) as f64 * cost;
                if traj.steps as f64 > s.max_steps || work > s.max_work {
                    return Err(Error::WorkLimit {
                        what: format!(
                            "steps ({}) or work units ({work:.3e}) at t = {t} s",
                            traj.steps
                        ),
                        estimate: (traj.steps as f64).max(work),
                        limit: if traj.steps as f64 > s.max_steps {
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
                    ws.proj.project(rhs.sys, q, v, true)?;
                }
                if let Some(c) = cov.as_mut() {
                    c.step(rhs.sys, s.method, &ws.qn, &ws.vn, &ws.tau_n, dt)?;
                    c.project(rhs.sys, q, v)?;
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
        traj.evaluations += rhs.evaluations;
        traj.least_squares_evaluations += rhs.least_squares;
        result.map_err(|e| match e {
            Error::Diverged { t: tt, message } if tt.is_nan() => Error::Diverged { t, message },
            e => e,
        })
    }
}
