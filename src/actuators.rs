//! Actuators that drive a prediction the way a robot is driven: joint velocity controllers (PI,
//! torque limited by the URDF `effort`), joint position controllers (PD), and a differential
//! drive whose commanded (v, ω) becomes wheel-speed targets for its two wheel controllers.
//!
//! Two models of the controllers in time (`actuators.hold`):
//! - `zero_order` (default): like a real digital controller, the torques are computed at the
//!   control period and held until the next tick; the integrators never step across a tick.
//! - `continuous`: the torques are a function of (t, q, v) evaluated at every stage, so the step
//!   follows the accuracy asked for, not the control period. A velocity controller's integral
//!   is then `∫(v* − q̇) dt = ∫v* dt − (q − q(0))`, exact for piecewise-constant targets, less
//!   what it did not integrate while saturated (the held model's conditional anti-windup): a
//!   controller found beyond its effort at a span's start holds its integral (`frozen`) until
//!   its torque comes back inside, at a time the run predicts from q̈ and steps to
//!   ([`Actuators::saturation_exit`]); the integral it skipped is kept as `windup`. Between those
//!   reviews the torque stays a function of (t, q, v). docs/performance.md gives its distance
//!   from the held model.

use crate::error::{Error, Result};
use crate::model::Model;
use serde::Deserialize;
use std::collections::BTreeMap;

mod continuous;
mod lag;
mod spec;
mod traction;

pub use lag::CommandLag;

pub use spec::{
    ActuatorsSpec, DEFAULT_CONTROL_PERIOD, DiffDriveSpec, Hold, PositionControllerSpec,
    VelocityControllerSpec,
};

/// What a prediction is asked to follow from a time on (piecewise constant).
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Command {
    /// Base (v [m/s], ω [rad/s]) for the differential drive.
    #[serde(default)]
    pub base_twist: Option<[f64; 2]>,
    /// Joint velocity targets [rad/s or m/s].
    #[serde(default)]
    pub joint_velocity: BTreeMap<String, f64>,
    /// Joint position targets [rad or m].
    #[serde(default)]
    pub joint_position: BTreeMap<String, f64>,
}

#[derive(Clone, Debug)]
struct Pi {
    iq: usize,
    iv: usize,
    kp: f64,
    ki: f64,
    effort: f64,
    integral: f64,
    /// Linear feedback (k, d) at the last tick ([`Actuators::feedback`]).
    gain: (f64, f64),
    /// Held: clamped at the last tick.
    clamped: bool,
    name: String,
    /// Continuous hold: the target of the current segment (NaN: none), ∫v* dt up to the
    /// segment's start, and the joint's position at the prediction's start.
    target: f64,
    /// Under a command lag ([`lag`]): the lagged target where the current segment (continuous
    /// hold) or the next tick (held) starts [rad/s or m/s]; NaN: on the command itself.
    lag_from: f64,
    target_integral: f64,
    q_start: f64,
    /// Continuous hold, anti-windup: the integral held while saturated (NaN: integrating) and
    /// the error integral skipped while saturated [rad or m].
    frozen: f64,
    windup: f64,
}

#[derive(Clone, Debug)]
struct Pd {
    iq: usize,
    iv: usize,
    kp: f64,
    kd: f64,
    effort: f64,
    /// Linear feedback (k, d) at the last tick ([`Actuators::feedback`]).
    gain: (f64, f64),
    name: String,
    /// Continuous hold: the target of the current segment (NaN: none).
    target: f64,
}

/// One controller's linear feedback at a tick, as a joint spring-damper on the state: its
/// torque moves by `−k δq − d δv` (q index `iq`, v index `iv`). A position controller is
/// (kp, kd). A velocity controller's integral is `∫(target − q̇) dt = target·t − (q − q(0))`,
/// so it acts as (ki, kp + ki·dt) with the joint's position as its state (`integral`) — the
/// position measured from where the prediction started: a perturbation of that start position
/// does not reach the controller (the covariance carries it apart, covariance_integral.rs). A
/// controller without a target, or saturated, has no feedback (0, 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Feedback {
    /// The joint's q index.
    pub iq: usize,
    /// The joint's v index (where its torque acts).
    pub iv: usize,
    /// [N·m/rad or N/m]
    pub k: f64,
    /// [N·m·s/rad or N·s/m]
    pub d: f64,
    /// A velocity controller's integral (k = ki).
    pub integral: bool,
    /// The torque's own rate at fixed (q, v) [N·m/s or N/s]: a continuous velocity controller's
    /// ki × target (its integral of the target grows with t); 0 for a held torque.
    pub rate: f64,
    /// The controller has a target and asks for more than its effort (or the traction torque):
    /// its torque is clamped.
    pub saturated: bool,
}

/// Validated actuators with their controller state.
#[derive(Clone, Debug, Default)]
pub struct Actuators {
    velocity: Vec<Pi>,
    position: Vec<Pd>,
    /// Indices into `velocity` of the left and right wheel controllers, r and b.
    diff_drive: Option<(usize, usize, f64, f64)>,
    /// Control period [s]: torques are recomputed every period and held in between.
    pub control_period: f64,
    /// The controllers' model in time.
    pub hold: Hold,
    /// Continuous hold: start of the current command segment [s].
    segment_start: f64,
    /// The diff drive's traction torque T [N·m] and load transfer κ (κ > 0: the wheels'
    /// clamps are coupled, [`traction`]).
    traction: (f64, f64),
    /// The diff drive's command lag τ [s] (0: none, [`lag`]).
    lag_s: f64,
}

impl Actuators {
    /// Validate `actuators:` against the model (1-DOF joints, gains finite and ≥ 0).
    pub fn new(model: &Model, spec: &ActuatorsSpec) -> Result<Self> {
        let period = spec.control_period.unwrap_or(DEFAULT_CONTROL_PERIOD);
        if !(period.is_finite() && period > 0.0) {
            return Err(Error::Invalid(format!(
                "actuators.control_period = {period} s must be positive"
            )));
        }
        let joint = |name: &str| -> Result<(usize, usize, f64)> {
            let b = model.joint_body(name)?;
            let j = &model.bodies[b].joint;
            if j.kind.nv() != 1 {
                return Err(Error::Invalid(format!(
                    "actuators: joint '{name}' is not a 1-DOF joint"
                )));
            }
            Ok((j.idx_q, j.idx_v, model.limits.effort[j.idx_v]))
        };
        let gains = |what: &str, g: &[f64]| -> Result<()> {
            if g.iter().any(|x| !x.is_finite() || *x < 0.0) {
                return Err(Error::Invalid(format!(
                    "actuators: {what}: gains must be finite and ≥ 0"
                )));
            }
            Ok(())
        };
        let mut a = Actuators {
            control_period: period,
            hold: spec.hold,
            ..Default::default()
        };
        for s in &spec.velocity {
            gains(&s.joint, &[s.kp, s.ki])?;
            let (iq, iv, effort) = joint(&s.joint)?;
            a.velocity.push(Pi {
                iq,
                iv,
                kp: s.kp,
                ki: s.ki,
                effort,
                integral: 0.0,
                gain: (0.0, 0.0),
                clamped: false,
                name: s.joint.clone(),
                target: f64::NAN,
                lag_from: f64::NAN,
                target_integral: 0.0,
                q_start: 0.0,
                frozen: f64::NAN,
                windup: 0.0,
            });
        }
        for s in &spec.position {
            gains(&s.joint, &[s.kp, s.kd])?;
            let (iq, iv, effort) = joint(&s.joint)?;
            a.position.push(Pd {
                iq,
                iv,
                kp: s.kp,
                kd: s.kd,
                effort,
                gain: (0.0, 0.0),
                name: s.joint.clone(),
                target: f64::NAN,
            });
        }
        if let Some(d) = &spec.diff_drive {
            gains("diff_drive", &[d.kp, d.ki])?;
            if !(d.wheel_radius > 0.0 && d.wheel_separation > 0.0) {
                return Err(Error::Invalid(
                    "actuators.diff_drive: wheel_radius and wheel_separation must be positive"
                        .into(),
                ));
            }
            if let Some(t) = d.traction_torque
                && !(t.is_finite() && t > 0.0)
            {
                return Err(Error::Invalid(format!(
                    "actuators.diff_drive.traction_torque = {t}: must be positive and finite [N·m]"
                )));
            }
            let mut idx = [0; 2];
            for (k, name) in [&d.left_joint, &d.right_joint].into_iter().enumerate() {
                let (iq, iv, effort) = joint(name)?;
                let effort = d.traction_torque.map_or(effort, |t| effort.min(t));
                a.velocity.push(Pi {
                    iq,
                    iv,
                    kp: d.kp,
                    ki: d.ki,
                    effort,
                    integral: 0.0,
                    gain: (0.0, 0.0),
                    clamped: false,
                    name: name.clone(),
                    target: f64::NAN,
                    lag_from: f64::NAN,
                    target_integral: 0.0,
                    q_start: 0.0,
                    frozen: f64::NAN,
                    windup: 0.0,
                });
                idx[k] = a.velocity.len() - 1;
            }
            a.diff_drive = Some((idx[0], idx[1], d.wheel_radius, d.wheel_separation));
            if let Some(kappa) = d.traction_load_transfer {
                let Some(t) = d
                    .traction_torque
                    .filter(|_| kappa.is_finite() && kappa >= 0.0)
                else {
                    return Err(Error::Invalid(format!(
                        "actuators.diff_drive.traction_load_transfer = {kappa}: must be finite, \
                         ≥ 0 and beside a traction_torque"
                    )));
                };
                a.traction = (t, kappa);
            }
            if let Some(tau) = d.command_lag {
                if !(tau.is_finite() && tau >= 0.0) {
                    return Err(Error::Invalid(format!(
                        "actuators.diff_drive.command_lag = {tau}: must be finite and ≥ 0 [s]"
                    )));
                }
                a.lag_s = if tau >= lag::MIN_LAG_S { tau } else { 0.0 };
            }
        }
        Ok(a)
    }

    /// True when the scene has no controller.
    pub fn is_empty(&self) -> bool {
        self.velocity.is_empty() && self.position.is_empty()
    }

    /// Reset the controllers' integral states.
    pub fn reset(&mut self) {
        self.velocity.iter_mut().for_each(|c| {
            (c.integral, c.lag_from) = (0.0, f64::NAN);
            (c.gain, c.clamped) = ((0.0, 0.0), false);
        });
        self.position.iter_mut().for_each(|c| c.gain = (0.0, 0.0));
    }

    /// The velocity controllers' integrals ∫(target − q̇) dt at a prediction's start [rad or
    /// m], by v index (nv; empty: all zero). Called after the start of the controllers' model
    /// in time ([`Actuators::start_continuous`] for the continuous hold).
    pub fn start_integrals(&mut self, integrals: &[f64]) {
        for c in &mut self.velocity {
            let i = integrals.get(c.iv).copied().unwrap_or(0.0);
            // Continuous hold: the integral is target_integral + ∫target − (q − q(0)), so the
            // start's integral is the target integral's start value.
            (c.integral, c.target_integral) = (i, i);
        }
    }

    /// The diff drive's command lag τ [s], where the scene declares one above 0.
    pub fn command_lag_s(&self) -> Option<f64> {
        (self.lag_s > 0.0).then_some(self.lag_s)
    }

    /// The base command (v [m/s], ω [rad/s]) whose wheel targets are the drive's wheel speeds in
    /// `v` (nv), through the drive's own `wheel_radius` and `wheel_separation`: where a lag
    /// starts when no command history says where it is. The wheels' PI loops hold their speeds
    /// on the lagged targets, so the speeds measure them. None without a diff drive or with a
    /// wheel speed not finite.
    pub fn drive_command_of_wheels(&self, v: &[f64]) -> Option<[f64; 2]> {
        let (l, r, radius, b) = self.diff_drive?;
        let (wl, wr) = (v[self.velocity[l].iv], v[self.velocity[r].iv]);
        let command = [radius * (wl + wr) / 2.0, radius * (wr - wl) / b];
        command.iter().all(|x| x.is_finite()).then_some(command)
    }

    /// The diff drive's lagged command (v [m/s], ω [rad/s]) at a prediction's start, where the
    /// drive has a command lag ([`CommandLag::at`] over the commands before it); None: the
    /// lag starts on the first command. Called after the start of the controllers' model in
    /// time, like [`Actuators::start_integrals`].
    pub fn start_lag(&mut self, lagged: Option<[f64; 2]>) {
        let (Some((l, r, radius, b)), Some([lin, ang])) = (self.diff_drive, lagged) else {
            return;
        };
        if self.lag_s > 0.0 {
            self.velocity[l].lag_from = (lin - ang * b / 2.0) / radius;
            self.velocity[r].lag_from = (lin + ang * b / 2.0) / radius;
        }
    }

    /// Each velocity controller's integral ∫(target − q̇) dt [rad or m] that makes its PI give
    /// the measured effort, into `out` (by v index): the inverse of
    /// τ = kp (target − q̇) + ki ∫(target − q̇) dt under `cmd`, at the measured joint velocities
    /// `v` and efforts `effort` (both nv; NaN: not measured). A controller without a target
    /// under `cmd` or without integral gain gets 0; one whose joint was not measured keeps its
    /// entry (joint states may come in several messages). An effort beyond the controller's
    /// limit counts as the limit: the least integral that reaches it.
    pub fn integrals_from_efforts(
        &self,
        cmd: &Command,
        v: &[f64],
        effort: &[f64],
        out: &mut [f64],
    ) {
        let drive = self.diff_drive;
        for (k, c) in self.velocity.iter().enumerate() {
            let (tau, w) = (effort[c.iv], v[c.iv]);
            match velocity_target(drive, cmd, k, &c.name) {
                Some(target) if c.ki > 0.0 => {
                    if tau.is_finite() && w.is_finite() {
                        out[c.iv] = (tau.clamp(-c.effort, c.effort) - c.kp * (target - w)) / c.ki;
                    }
                }
                _ => out[c.iv] = 0.0,
            }
        }
    }

    /// The controllers' linear feedback at their last tick, velocity controllers first, in a
    /// fixed order (module doc of [`Feedback`]).
    pub fn feedback(&self) -> impl Iterator<Item = Feedback> + '_ {
        let of = |(iq, iv), (k, d), integral, rate, saturated| Feedback {
            iq,
            iv,
            k,
            d,
            integral,
            rate,
            saturated,
        };
        let continuous = self.is_continuous();
        let pi = self.velocity.iter().map(move |c| {
            let rate = match continuous && c.target.is_finite() {
                true => {
                    let (target, target_rate) = self.target_at(c, self.segment_start);
                    c.gain.0 * target + c.gain.1 * target_rate
                }
                false => 0.0,
            };
            let saturated = match continuous {
                true => c.target.is_finite() && c.frozen.is_finite(),
                false => c.clamped,
            };
            of((c.iq, c.iv), c.gain, true, rate, saturated)
        });
        let pd = self
            .position
            .iter()
            .map(move |c| of((c.iq, c.iv), c.gain, false, 0.0, false));
        pi.chain(pd)
    }

    /// Check that a command names only joints that have controllers.
    pub fn check_command(&self, cmd: &Command) -> Result<()> {
        for name in cmd.joint_velocity.keys() {
            if !self.velocity.iter().any(|c| &c.name == name) {
                return Err(Error::Invalid(format!(
                    "command: joint '{name}' has no velocity controller"
                )));
            }
        }
        for name in cmd.joint_position.keys() {
            if !self.position.iter().any(|c| &c.name == name) {
                return Err(Error::Invalid(format!(
                    "command: joint '{name}' has no position controller"
                )));
            }
        }
        if cmd.base_twist.is_some() && self.diff_drive.is_none() {
            return Err(Error::Invalid(
                "command: base_twist given but the scene has no actuators.diff_drive".into(),
            ));
        }
        let all: Vec<f64> = cmd
            .joint_velocity
            .values()
            .chain(cmd.joint_position.values())
            .copied()
            .chain(cmd.base_twist.into_iter().flatten())
            .collect();
        crate::error::check_finite("command", &all)
    }

    /// One control tick at (q, v): update the integrators over `dt` and write the held torques.
    pub fn update(&mut self, cmd: &Command, q: &[f64], v: &[f64], dt: f64, tau: &mut [f64]) {
        tau.iter_mut().for_each(|x| *x = 0.0);
        let (drive, lag_s) = (self.diff_drive, self.lag_s);
        // Under a lag the tick's target is the lagged one where the tick starts.
        let held = |c: &Pi, target: f64| match lag_s > 0.0 && c.lag_from.is_finite() {
            true => c.lag_from,
            false => target,
        };
        let raw_of = |k: usize, c: &Pi| {
            velocity_target(drive, cmd, k, &c.name).map(|target| {
                let e = held(c, target) - v[c.iv];
                c.kp * e + c.ki * (c.integral + e * dt)
            })
        };
        let limits = self.wheel_limits(|k, c| raw_of(k, c).unwrap_or(0.0));
        for (k, c) in self.velocity.iter_mut().enumerate() {
            let Some(command) = velocity_target(drive, cmd, k, &c.name) else {
                (c.gain, c.clamped) = ((0.0, 0.0), false);
                continue;
            };
            let target = held(c, command);
            if lag_s > 0.0 && is_wheel(drive, k) {
                c.lag_from = lag::value(target, command, lag_s, dt);
            }
            let e = target - v[c.iv];
            let raw = c.kp * e + c.ki * (c.integral + e * dt);
            let effort = traction::effort(limits, k, c.effort);
            c.clamped = raw.abs() > effort;
            c.gain = if !c.clamped {
                c.integral += e * dt; // anti-windup: integrate only when not saturated
                (c.ki, c.kp + c.ki * dt)
            } else {
                (0.0, 0.0)
            };
            tau[c.iv] += raw.clamp(-effort, effort);
        }
        for c in &mut self.position {
            let Some(&target) = cmd.joint_position.get(&c.name) else {
                c.gain = (0.0, 0.0);
                continue;
            };
            let raw = c.kp * (target - q[c.iq]) - c.kd * v[c.iv];
            c.gain = if raw.abs() <= c.effort {
                (c.kp, c.kd)
            } else {
                (0.0, 0.0)
            };
            tau[c.iv] += raw.clamp(-c.effort, c.effort);
        }
    }
}

/// Whether velocity controller `k` drives one of the diff drive's wheels (what a command lag
/// acts on).
fn is_wheel(drive: Option<(usize, usize, f64, f64)>, k: usize) -> bool {
    drive.is_some_and(|(l, r, _, _)| k == l || k == r)
}

/// The target of velocity controller `k` (named `name`) under `cmd`: a base twist gives the
/// diff drive's wheels theirs, replacing their own (no buffer: a control tick runs inside the
/// prediction's loop and allocates nothing).
fn velocity_target(
    drive: Option<(usize, usize, f64, f64)>,
    cmd: &Command,
    k: usize,
    name: &str,
) -> Option<f64> {
    match (drive, cmd.base_twist) {
        (Some((l, _, radius, b)), Some([lin, ang])) if k == l => {
            Some((lin - ang * b / 2.0) / radius)
        }
        (Some((_, r, radius, b)), Some([lin, ang])) if k == r => {
            Some((lin + ang * b / 2.0) / radius)
        }
        _ => cmd.joint_velocity.get(name).copied(),
    }
}
