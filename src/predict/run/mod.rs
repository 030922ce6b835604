//! The prediction loop of one run: control ticks, integration spans of the answer and its error
//! estimate's companion, drift control, the covariance beside them, samples, and the energy
//! check of fixed explicit steps on passive, conservative scenes. `advance.rs` integrates one
//! span of a lane, `rhs.rs` is the right-hand side its integrator evaluates.

mod advance;
pub(in crate::predict) mod rhs;
mod sample;

use crate::actuators::Command;
use crate::constraints::ContactLimits;
use crate::error::{Error, Result};
use crate::predict::covariance::CovariancePropagator;
use crate::predict::covariance::worker::with_worker;
use crate::predict::error_kinds::ByKind;
use crate::predict::estimate::{self, Lane};
use crate::predict::predictor::Predictor;
use crate::predict::request::{CovarianceSamples, PredictionRequest};
use crate::predict::settings::IntegrationSettings;
use crate::predict::trajectory::{Sample, Trajectory};
use advance::companion_error;

/// Pieces a span is cut into at most where frozen controllers come back inside their effort
/// (two wheels, each once, and a retry for each prediction that came early).
const MAX_PIECES: usize = 6;
/// The shortest piece [s]: a predicted return closer than this is taken at the piece's end.
const MIN_PIECE: f64 = 1e-4;

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
    /// Record forces in the samples, judging the contacts under these limits.
    forces: Option<&'a ContactLimits>,
    /// The samples P is brought up to (always the horizon's).
    covariance_samples: CovarianceSamples<'a>,
}

impl Predictor {
    /// One run of `req` over `horizon` [s] under the resolved settings `s`, the controllers
    /// ticking every `control` [s].
    pub(in crate::predict) fn run(
        &mut self,
        req: &PredictionRequest,
        horizon: f64,
        s: &IntegrationSettings,
        control: Option<f64>,
    ) -> Result<Trajectory> {
        let (q0, v0) = (req.q0, req.v0);
        let mut q = q0.to_vec();
        self.model.normalize(&mut q);
        self.check_step_size(&q, v0, s)?;
        // The run's controllers start from the configuration's, at rest.
        self.actuators.clone_from(&self.config.actuators);
        if let Some(p) = control {
            self.actuators.control_period = p;
        }
        if self.actuators.is_continuous() {
            self.actuators.start_continuous(&q);
        }
        self.actuators.start_integrals(req.controller_integrals);
        self.actuators.start_lag(req.lagged_command);
        self.ws.tau_act.iter_mut().for_each(|x| *x = 0.0);
        self.ws.companion_actuators.clone_from(&self.actuators);
        self.ws.tau_companion.iter_mut().for_each(|x| *x = 0.0);
        let companion = estimate::companion_settings(s);
        let factor = estimate::richardson_factor(s.method);
        // The lanes leave the workspace while they step (disjoint borrows), and come back.
        // A probe left by an earlier run (one that failed before its step) is no one's.
        self.ws.probe_t = None;
        let mut lanes = std::mem::take(&mut self.ws.lanes);
        lanes[0].start(&q, v0, s.dt);
        lanes[1].start(&q, v0, companion.dt);
        let result = self.run_lanes(&mut lanes, req, horizon, (s, &companion), factor);
        self.ws.lanes = lanes;
        result
    }

    /// The loop of [`Predictor::run`] over control ticks and samples, the answer in `lanes[0]`,
    /// the error estimate's companion in `lanes[1]` under settings `s.1`.
    fn run_lanes(
        &mut self,
        lanes: &mut [Lane; 2],
        req: &PredictionRequest,
        horizon: f64,
        s: (&IntegrationSettings, &IntegrationSettings),
        factor: f64,
    ) -> Result<Trajectory> {
        let (s, companion) = s;
        let commands = req.commands;
        self.covariance = match req.start_covariance {
            Some(p0) => Some(CovariancePropagator::start(
                &mut self.sys,
                self.ws.gains,
                &self.forces,
                &self.actuators.feedback().collect::<Vec<_>>(),
                &self.config.uncertainty,
                p0,
                (0.0, &lanes[0].q, &lanes[0].v),
            )?),
            None => None,
        };
        let period = if self.actuators.is_empty() || self.actuators.is_continuous() {
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
            // One sample per period and the start (the request's budget bounds the count).
            samples: Vec::with_capacity(
                (horizon / s.sample_period).min(s.max_samples).max(0.0) as usize + 2,
            ),
            contact_check: None,
            start_off_constraints: None,
            saturated_s: 0.0,
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
        if self.actuators.is_continuous() {
            self.actuators.begin_segment(command_at(0.0), 0.0);
            let a = &lanes[0];
            (self.actuators).continuous_torque(0.0, &a.q, &a.v, &mut self.ws.tau_act);
        } else if !self.actuators.is_empty() && horizon > 0.0 {
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
        let read_p = |t: f64| req.covariance_samples.at(t, s.sample_period, horizon);
        let forces = req.forces.then_some(&req.contact_limits);
        // A measured start is never exactly on the constraints: its forces are those of its
        // projection (the drift control's, as the steps end), not of rows that disagree there.
        let projected = match forces {
            Some(_) if !self.sys.constraints().is_empty() => {
                let (mut q, mut v) = (lanes[0].q.clone(), lanes[0].v.clone());
                let off = (self.ws.ls).project_measured(&mut self.sys, &mut q, &mut v)?;
                traj.start_off_constraints = Some(off);
                Some((q, v))
            }
            _ => None,
        };
        let first = self.sample(
            0.0,
            (&lanes[0].q, &lanes[0].v),
            projected.as_ref().map(|(q, v)| (&q[..], &v[..])),
            s.error_estimate.then(ByKind::default),
            (forces, read_p(0.0)),
        )?;
        let springs = self
            .forces
            .potential_energy(self.sys.model(), self.sys.data(), &lanes[0].q);
        let mut guard = EnergyGuard::new(&first, springs, self.energy_guard_applies(s));
        traj.samples.push(first);
        let plan = Plan {
            commands,
            horizon,
            period,
            s,
            companion,
            factor,
            forces,
            covariance_samples: req.covariance_samples,
        };
        let parallel = self.config.parallel_covariance
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
        traj.jacobians = a.radau.jacobians + a.step.jacobians;
        traj.estimate_evaluations = c.evaluations;
        if let Some(cov) = &self.covariance {
            (traj.covariance_linearizations, traj.covariance_time_s) =
                (cov.linearizations, cov.time_s);
        }
        if let Some(limits) = forces {
            let samples = traj.samples.iter().map(|s| (s.t, s.contacts.as_deref()));
            traj.contact_check = Some(self.contact_judge.check(samples, limits));
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
            covariance_samples,
        } = *plan;
        let idle = Command::default();
        let command_at = |t: f64| command_at(commands, &idle, t);
        let (mut t, mut k) = (0.0, 0usize);
        let mut next_sample = s.sample_period;
        let continuous = self.actuators.is_continuous();
        // Pieces stepped on ROS2's current F (none yet), and the answer's F the companion took
        // last.
        let (mut on_f, mut shared, mut gains_changed) = (usize::MAX, usize::MAX, false);
        while t < horizon - 1e-12 {
            k += 1;
            let mut t_end = (k as f64 * period).min(horizon);
            if continuous {
                // A span ends where a command starts, so that each span has one target.
                if let Some(&(tc, _)) = commands.iter().find(|(tc, _)| *tc > t + 1e-12)
                    && tc < t_end - 1e-12
                {
                    t_end = tc;
                    k -= 1;
                }
                // A controller that gains or loses its target changes F's form (below).
                gains_changed = t > 0.0 && self.actuators.begin_segment(command_at(t), t);
            } else if !self.actuators.is_empty() && k > 1 {
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
            if continuous && (commands.iter()).any(|&(tc, _)| t > 0.0 && (tc - t).abs() <= 1e-12) {
                // A new target moves only F's ∂q̈/∂t (the controllers' ramp): each lane's is
                // recomputed from its F's ∂q̈/∂τ instead of a new F.
                for lane in lanes.iter_mut() {
                    let state = (t, &lane.q[..], &lane.v[..]);
                    lane.step.scratch.retarget(&self.actuators, state);
                }
            }
            // Continuous controllers: the span in pieces, each ending where a frozen
            // controller's torque is predicted back inside its effort (anti-windup,
            // actuators.rs), the modes reviewed at each piece's start.
            let (mut ts, mut pieces) = (t, 0);
            while ts < t_end - 1e-12 {
                let mut te = t_end;
                let mut changed = std::mem::take(&mut gains_changed);
                if continuous {
                    let a = &mut lanes[0];
                    changed |= self.actuators.review_saturation(ts, &a.q, &a.v);
                    if self.actuators.any_frozen() && pieces < MAX_PIECES {
                        self.probe_accel(a, ts)?;
                        let exit =
                            (self.actuators).saturation_exit(ts, &a.q, &a.v, &self.ws.probe_qdd);
                        if let Some(dt) = exit {
                            te = (ts + dt.max(MIN_PIECE)).min(t_end);
                            if t_end - te < MIN_PIECE {
                                te = t_end;
                            }
                        }
                    }
                }
                // ROS2's F: fresh every `jacobian_spans` pieces; where a controller's feedback
                // left or entered, the current F re-formed for it (integrators/mod.rs,
                // `JacobianScratch`), or a fresh one where it cannot be.
                let mut fresh = on_f >= s.jacobian_spans;
                if changed && !fresh && s.method.integrator().is_w_method() {
                    let a = &mut lanes[0];
                    fresh = !a.step.reform(&self.actuators, (ts, &a.q, &a.v));
                }
                if fresh {
                    on_f = 0;
                }
                if self.actuators.feedback().any(|f| f.saturated) {
                    traj.saturated_s += te - ts;
                }
                let f = (fresh, &mut shared);
                self.advance_piece(lanes, (ts, te), s, companion, f)?;
                (ts, pieces, on_f) = (te, pieces + 1, on_f.saturating_add(1));
            }
            t = t_end;
            if t >= next_sample - 1e-9 || t >= horizon - 1e-12 {
                // Where P is read, the recorded steps are linearized now (a chunk may span
                // control ticks and samples; covariance/chunks.rs checks that it reproduces
                // them).
                let read_p = covariance_samples.at(t, s.sample_period, horizon);
                if let Some(cov) = self.covariance.as_mut().filter(|_| read_p) {
                    cov.flush(&mut self.sys, s.method, true)?;
                } else if let Some(pipe) = self.ws.pipe.get_mut().filter(|_| read_p) {
                    pipe.handoff(t, Some(traj.samples.len()))?;
                }
                let [a, c] = &*lanes;
                if continuous {
                    // The sample's forces and torques under the controllers at its state.
                    (self.actuators).continuous_torque(t, &a.q, &a.v, &mut self.ws.tau_act);
                }
                let e = s.error_estimate.then(|| {
                    estimate::estimate(&self.model, &a.q, &c.q, factor, &mut self.ws.diff)
                });
                let mut sample = self.sample(t, (&a.q, &a.v), None, e, (forces, read_p))?;
                sample.saturated_s = traj.saturated_s;
                let springs = self
                    .forces
                    .potential_energy(self.sys.model(), self.sys.data(), &a.q);
                guard.check(&sample, springs, a.steps, s)?;
                traj.samples.push(sample);
                if let Some(over) = e.and_then(|e| estimate::check(s, &e, t, horizon)) {
                    return Err(over);
                }
                while next_sample <= t + 1e-9 {
                    next_sample += s.sample_period;
                }
            }
        }
        Ok(())
    }

    /// Both lanes over one piece (t0, t1) of a span: the answer, then the error estimate's
    /// companion; ROS2 with a fresh F if `fresh_jacobian`, the companion taking the answer's
    /// when it is not the one it took last (`shared`: the version of the answer's F it took, `StepWorkspace::forms`).
    fn advance_piece(
        &mut self,
        lanes: &mut [Lane; 2],
        (t0, t1): (f64, f64),
        s: &IntegrationSettings,
        companion: &IntegrationSettings,
        (fresh_jacobian, shared): (bool, &mut usize),
    ) -> Result<()> {
        let (answer, comp) = lanes.split_at_mut(1);
        if s.method.integrator().is_w_method() && fresh_jacobian {
            // The order holds with any F, but an older one damps the stiff modes less exactly
            // (settings.rs, `jacobian_spans`); the companion steps with the answer's.
            answer[0].step.invalidate();
        }
        let work = comp[0].evaluations;
        let largest = self.advance(&mut answer[0], None, work, (t0, t1), s)?;
        if s.error_estimate {
            // Its W follows its own dt when the F is the one it took last.
            if s.method.integrator().is_w_method() && answer[0].step.forms != *shared {
                comp[0].step.share_jacobian(&answer[0].step);
                *shared = answer[0].step.forms;
            }
            let work = answer[0].evaluations;
            let cap = Some(0.5 * largest);
            self.advance(&mut comp[0], cap, work, (t0, t1), companion)
                .map_err(companion_error)?;
        }
        Ok(())
    }

    /// The energy check runs for passive, conservative scenes stepped by a fixed explicit method.
    fn energy_guard_applies(&self, s: &IntegrationSettings) -> bool {
        !s.method.integrator().is_implicit()
            && !s.method.is_adaptive()
            && self.actuators.is_empty()
            && self.forces.is_conservative()
            && s.max_energy_error.is_finite()
    }
}

/// `max_energy_error`: for a passive, conservative scene stepped by a fixed explicit method, the
/// energy may not move by more than this fraction of the energy in motion (the largest kinetic
/// plus spring energy, or gravity energy exchanged, seen so far), checked at every sample from the
/// 16th step on: past it the step is too large and the answer would be wrong, so the prediction stops with
/// `Error::Diverged` instead.
struct EnergyGuard {
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
    fn new(first: &Sample, springs: f64, on: bool) -> Self {
        Self {
            on,
            e0: first.kinetic_energy + first.potential_energy,
            pe0: first.potential_energy - springs,
            scale: first.kinetic_energy + springs,
        }
    }

    fn check(
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
