//! The prediction loop: control ticks, integration steps, drift control, samples.

use super::advance::{JacobianWork, companion_error};
use super::covariance::{CovariancePropagator, UncertaintySpec};
use super::covariance_worker::{PipeSlot, with_worker};
use super::drift::Projector;
use super::estimate::{self, Lane, MAX_REFINEMENTS};
use super::guard::{EnergyGuard, check_work};
use super::integrator::Method;
use super::trajectory::{PredictOptions, Trajectory};
use super::{DriftControl, IntegrationSettings};
use crate::actuators::{Actuators, Command};
use crate::dynamics::Baumgarte;
use crate::error::{Error, Result};
use crate::forces::ForceElements;
use crate::model::Model;
use crate::scene::Scene;
use crate::system::System;
use nalgebra::DMatrix;
use std::time::Instant;

/// Buffers of a run, sized once per model (the stepping loop allocates nothing).
#[derive(Clone, Debug, Default)]
pub(super) struct Workspace {
    /// The answer (0) and the error estimate's companion (1) (estimate.rs).
    pub(super) lanes: [Lane; 2],
    /// Tangent-space difference of the two lanes' q (nv).
    pub(super) diff: Vec<f64>,
    /// Least-squares constrained accelerations at singular configurations.
    pub(super) ls: Projector,
    pub(super) tau: Vec<f64>,
    pub(super) tau_act: Vec<f64>,
    /// The companion's own controllers and their torque: feedback acts on the state it is
    /// computed from, so each lane closes its own loop (with the answer's torques the companion
    /// would run open-loop and drift away along any unstable mode — an arm held up by its PD).
    pub(super) companion_actuators: Actuators,
    pub(super) tau_companion: Vec<f64>,
    pub(super) zero: Vec<f64>,
    /// The state and applied force at the start of a step (covariance propagation).
    pub(super) qn: Vec<f64>,
    pub(super) vn: Vec<f64>,
    pub(super) tau_n: Vec<f64>,
    /// The state the drift projection left with its rows evaluated (advance.rs, `RowsAt`).
    pub(super) rows_q: Vec<f64>,
    pub(super) rows_v: Vec<f64>,
    /// The implicit methods' Jacobian (advance.rs).
    pub(super) jw: JacobianWork,
    /// Work units of one dynamics evaluation (`limits::evaluation_cost`).
    pub(super) cost: f64,
    /// The covariance worker's pipe while a run has one.
    pub(super) pipe: PipeSlot,
}

/// The command in force at t [s] (the last one started; `idle` before the first), borrowed: a
/// clone per control tick allocated its maps.
fn command_at<'a>(commands: &'a [(f64, Command)], idle: &'a Command, t: f64) -> &'a Command {
    commands
        .iter()
        .rev()
        .find(|(ts, _)| *ts <= t + 1e-12)
        .map_or(idle, |(_, c)| c)
}

/// What a run's loop follows (`Predictor::step_loop`).
struct Plan<'a> {
    commands: &'a [(f64, Command)],
    horizon: f64,
    /// Control period (or sample period without actuators) [s].
    period: f64,
    s: &'a IntegrationSettings,
    /// The error estimate companion's settings and Richardson factor (estimate.rs).
    companion: &'a IntegrationSettings,
    factor: f64,
    /// Record forces in the samples.
    forces: bool,
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
    /// Propagate the covariance on a second thread, one sample behind the prediction, when the
    /// machine has more than one core (covariance_worker.rs; the same P to the bit). Default
    /// true.
    pub parallel_covariance: bool,
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
            lanes: [Lane::new(&sys), Lane::new(&sys)],
            diff: vec![0.0; nv],
            ls: Projector::new(&sys),
            tau: vec![0.0; nv],
            tau_act: vec![0.0; nv],
            companion_actuators: Actuators::default(),
            tau_companion: vec![0.0; nv],
            zero: vec![0.0; nv],
            qn: vec![0.0; nq],
            vn: vec![0.0; nv],
            tau_n: vec![0.0; nv],
            rows_q: vec![0.0; nq],
            rows_v: vec![0.0; nv],
            cost: crate::limits::evaluation_cost(&model),
            jw: JacobianWork::new(&sys),
            pipe: PipeSlot::default(),
        };
        Ok(Self {
            sys,
            forces,
            actuators,
            settings,
            want_forces: false,
            uncertainty: UncertaintySpec::default(),
            start_covariance: None,
            parallel_covariance: true,
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
        let mut s = self.settings.clone();
        let mut refinements = 0;
        let result = loop {
            let saved_gains = self.sys.baumgarte;
            if s.drift == DriftControl::Baumgarte && self.sys.baumgarte == Baumgarte::default() {
                self.sys.baumgarte = Baumgarte::from_time_constant(s.baumgarte_steps * s.dt);
            }
            let result = self.run(q0, v0, commands, horizon, &s, opts);
            self.sys.baumgarte = saved_gains;
            match result {
                // `adapt`: rerun with the step or tolerance the estimate asks for, bounded.
                Err(Error::ErrorEstimateExceeded { t, estimate, .. })
                    if s.adapt && refinements < MAX_REFINEMENTS =>
                {
                    s = estimate::refined(&s, estimate, t, horizon);
                    check_work(&s, &self.model, control, horizon)?;
                    refinements += 1;
                }
                r => break r,
            }
        };
        let mut traj = result?;
        traj.refinements = refinements;
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
        let mut q = q0.to_vec();
        self.model.normalize(&mut q);
        self.check_step_size(&q, v0, s)?;
        self.actuators.reset();
        self.ws.tau_act.iter_mut().for_each(|x| *x = 0.0);
        self.ws.companion_actuators.clone_from(&self.actuators);
        self.ws.tau_companion.iter_mut().for_each(|x| *x = 0.0);
        let companion = estimate::companion_settings(s);
        let factor = estimate::richardson_factor(s.method);
        // The lanes leave the workspace while they step (disjoint borrows), and come back.
        let mut lanes = std::mem::take(&mut self.ws.lanes);
        lanes[0].start(&q, v0, s.dt);
        lanes[1].start(&q, v0, companion.dt);
        let result = self.run_lanes(&mut lanes, commands, horizon, (s, &companion), factor, opts);
        self.ws.lanes = lanes;
        result
    }

    /// The loop of [`Predictor::run`] over control ticks and samples, the answer in `lanes[0]`,
    /// the error estimate's companion in `lanes[1]` under settings `s.1`.
    fn run_lanes(
        &mut self,
        lanes: &mut [Lane; 2],
        commands: &[(f64, Command)],
        horizon: f64,
        s: (&IntegrationSettings, &IntegrationSettings),
        factor: f64,
        opts: PredictOptions,
    ) -> Result<Trajectory> {
        let (s, companion) = s;
        if self.start_covariance.is_some() && self.forces.has_point_springs() {
            // Each step's linearization holds the applied generalized force apart from joint
            // spring-dampers: a point spring's stiffness would be missing from Φ and the
            // covariance silently wrong.
            return Err(Error::Unsupported {
                what: "covariance propagation with point-to-point springs (`forces.springs`)"
                    .into(),
                why: "their dependence on the configuration is not linearized yet (joint \
                      spring-dampers are); predict without a start covariance"
                    .into(),
            });
        }
        self.covariance = match &self.start_covariance {
            Some(p0) => Some(CovariancePropagator::start(
                &mut self.sys,
                &self.forces,
                &self.actuators.feedback().collect::<Vec<_>>(),
                &self.uncertainty,
                p0,
                &lanes[0].q,
                &lanes[0].v,
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
            dt: s.dt,
            rtol: s.rtol,
            samples: vec![],
            steps: 0,
            evaluations: 0,
            least_squares_evaluations: 0,
            jacobians: 0,
            estimate_evaluations: 0,
            covariance_linearizations: 0,
            covariance_time_s: 0.0,
            covariance_on_worker: false,
            refinements: 0,
            run_time_s: 0.0,
        };
        // The first control tick comes before the first sample, so that every sample's forces
        // include the actuator torque held over the interval that ends (or, at t = 0, starts) there.
        let idle = Command::default();
        let command_at = |t: f64| command_at(commands, &idle, t);
        if !self.actuators.is_empty() && horizon > 0.0 {
            let [a, c] = &*lanes;
            let cmd = command_at(0.0);
            let dt = period.min(horizon);
            self.actuators
                .update(cmd, &a.q, &a.v, dt, &mut self.ws.tau_act);
            if s.error_estimate {
                let ws = &mut self.ws;
                ws.companion_actuators
                    .update(cmd, &c.q, &c.v, dt, &mut ws.tau_companion);
            }
        }
        let first = self.sample(
            0.0,
            &lanes[0].q,
            &lanes[0].v,
            s.error_estimate.then_some(0.0),
            opts.forces,
        )?;
        let springs = self
            .forces
            .potential_energy(&self.sys.model, &self.sys.data, &lanes[0].q);
        let mut guard = EnergyGuard::new(&first, springs, self.energy_guard_applies(s));
        traj.samples.push(first);
        let plan = Plan {
            commands,
            horizon,
            period,
            s,
            companion,
            factor,
            forces: opts.forces,
        };
        let parallel = self.parallel_covariance
            && std::thread::available_parallelism().is_ok_and(|n| n.get() > 1);
        let result = match self.covariance.take() {
            Some(cov) if parallel => {
                traj.covariance_on_worker = true;
                let worker_sys = self.sys.clone();
                let (result, done) = with_worker(cov, worker_sys, s.method, |pipe| {
                    self.ws.pipe.set(Some(pipe));
                    let result = self.step_loop(lanes, &plan, &mut traj, &mut guard);
                    self.ws.pipe.set(None);
                    result
                });
                self.covariance = Some(done.propagator);
                for (k, rows) in done.snapshots {
                    traj.samples[k].covariance = Some(rows);
                }
                match done.error {
                    Some(e) => Err(e),
                    None => result,
                }
            }
            cov => {
                self.covariance = cov;
                self.step_loop(lanes, &plan, &mut traj, &mut guard)
            }
        };
        let [a, c] = &*lanes;
        traj.steps = a.steps;
        traj.evaluations = a.evaluations;
        traj.least_squares_evaluations = a.least_squares;
        traj.jacobians = a.radau.jacobians;
        traj.estimate_evaluations = c.evaluations;
        if let Some(cov) = &self.covariance {
            (traj.covariance_linearizations, traj.covariance_time_s) =
                (cov.linearizations, cov.time_s);
        }
        result.map(|()| traj)
    }

    /// The control ticks and samples of a run after its first sample (`Plan`), the answer in
    /// `lanes[0]`, the companion in `lanes[1]`; samples into `traj`.
    fn step_loop(
        &mut self,
        lanes: &mut [Lane; 2],
        plan: &Plan,
        traj: &mut Trajectory,
        guard: &mut EnergyGuard,
    ) -> Result<()> {
        let Plan {
            commands,
            horizon,
            period,
            s,
            companion,
            factor,
            forces,
        } = *plan;
        let idle = Command::default();
        let command_at = |t: f64| command_at(commands, &idle, t);
        let (mut t, mut k) = (0.0, 0usize);
        let mut next_sample = s.sample_period;
        while t < horizon - 1e-12 {
            k += 1;
            let t_end = (k as f64 * period).min(horizon);
            if !self.actuators.is_empty() && k > 1 {
                let [a, c] = &*lanes;
                let cmd = command_at(t);
                self.actuators
                    .update(cmd, &a.q, &a.v, t_end - t, &mut self.ws.tau_act);
                if s.error_estimate {
                    let ws = &mut self.ws;
                    ws.companion_actuators.update(
                        cmd,
                        &c.q,
                        &c.v,
                        t_end - t,
                        &mut ws.tau_companion,
                    );
                }
            }
            let (answer, comp) = lanes.split_at_mut(1);
            let work = comp[0].evaluations;
            let largest = self.advance(&mut answer[0], None, work, (t, t_end), s)?;
            if s.error_estimate {
                let work = answer[0].evaluations;
                let cap = Some(0.5 * largest);
                self.advance(&mut comp[0], cap, work, (t, t_end), companion)
                    .map_err(companion_error)?;
            }
            t = t_end;
            if t >= next_sample - 1e-9 || t >= horizon - 1e-12 {
                // P is read here: the recorded steps are linearized now (a chunk may span
                // control ticks; covariance_chunks.rs checks that it reproduces them).
                if let Some(cov) = self.covariance.as_mut() {
                    self.sys.cdata.t = t;
                    cov.flush(&mut self.sys, s.method)?;
                } else if let Some(pipe) = self.ws.pipe.get_mut() {
                    pipe.handoff(t, Some(traj.samples.len()))?;
                }
                let [a, c] = &*lanes;
                let e = s.error_estimate.then(|| {
                    estimate::estimate(&self.model, &a.q, &c.q, factor, &mut self.ws.diff)
                });
                let sample = self.sample(t, &a.q, &a.v, e, forces)?;
                let springs = self
                    .forces
                    .potential_energy(&self.sys.model, &self.sys.data, &a.q);
                guard.check(&sample, springs, a.steps, s)?;
                traj.samples.push(sample);
                if let Some(e) = e.filter(|&e| e > s.max_error) {
                    return Err(estimate::exceeded(s, e, t, horizon));
                }
                while next_sample <= t + 1e-9 {
                    next_sample += s.sample_period;
                }
            }
        }
        Ok(())
    }

    /// The energy check runs for passive, conservative scenes stepped by a fixed explicit method.
    fn energy_guard_applies(&self, s: &IntegrationSettings) -> bool {
        matches!(s.method, Method::SemiImplicitEuler | Method::Rk4)
            && self.actuators.is_empty()
            && self.forces.is_conservative()
            && s.max_energy_error.is_finite()
    }
}
