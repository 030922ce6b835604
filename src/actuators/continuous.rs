//! `hold: continuous`: the controllers' torques as a function of (t, q, v) within a command
//! segment, and the anti-windup reviewed between steps (module doc of `actuators`).

use super::{Actuators, Command, Feedback, Hold, Pi, is_wheel, lag, traction, velocity_target};

impl Actuators {
    /// The torques are a function of (t, q, v) (`hold: continuous`).
    pub fn is_continuous(&self) -> bool {
        self.hold == Hold::Continuous && !self.is_empty()
    }

    /// Continuous hold: a prediction starts at t = 0 from configuration `q`, with no target yet.
    pub fn start_continuous(&mut self, q: &[f64]) {
        self.segment_start = 0.0;
        for c in &mut self.velocity {
            (c.target, c.target_integral, c.q_start) = (f64::NAN, 0.0, q[c.iq]);
            c.lag_from = f64::NAN;
            (c.frozen, c.windup) = (f64::NAN, 0.0);
            c.gain = (0.0, 0.0);
        }
        for c in &mut self.position {
            c.target = f64::NAN;
            c.gain = (0.0, 0.0);
        }
    }

    /// Continuous hold: `cmd` is in force from t [s] on (the previous target's integral is
    /// closed at t). The feedback of [`Actuators::feedback`] is then each controller's
    /// unsaturated gain: (ki, kp) for a velocity controller, (kp, kd) for a position one.
    /// Returns whether that feedback changed (a controller gained or lost its target), which
    /// changes the form of the right-hand side's Jacobian; a new target alone moves only its
    /// ∂q̈/∂t.
    pub fn begin_segment(&mut self, cmd: &Command, t: f64) -> bool {
        let (drive, tau) = (self.diff_drive, self.lag_s);
        let elapsed = t - self.segment_start;
        let mut changed = false;
        for (k, c) in self.velocity.iter_mut().enumerate() {
            let lagged = tau > 0.0 && is_wheel(drive, k);
            if c.target.is_finite() {
                let (integral, now) = match lagged && c.lag_from.is_finite() {
                    true => (
                        lag::integral(c.lag_from, c.target, tau, elapsed),
                        lag::value(c.lag_from, c.target, tau, elapsed),
                    ),
                    false => (c.target * elapsed, c.target),
                };
                c.target_integral += integral;
                c.lag_from = now;
            }
            c.target = velocity_target(drive, cmd, k, &c.name).unwrap_or(f64::NAN);
            // The lag starts where the last segment (or the start) left it, else on this
            // command.
            c.lag_from = match lagged && c.target.is_finite() {
                true if c.lag_from.is_finite() => c.lag_from,
                true => c.target,
                false => f64::NAN,
            };
            let gain = if c.target.is_finite() && c.frozen.is_nan() {
                (c.ki, c.kp)
            } else {
                (0.0, 0.0)
            };
            changed |= gain != c.gain;
            c.gain = gain;
        }
        for c in &mut self.position {
            c.target = cmd.joint_position.get(&c.name).copied().unwrap_or(f64::NAN);
            let gain = if c.target.is_finite() {
                (c.kp, c.kd)
            } else {
                (0.0, 0.0)
            };
            changed |= gain != c.gain;
            c.gain = gain;
        }
        self.segment_start = t;
        changed
    }

    /// Continuous hold: the controllers' torques at (t, q, v) into `tau` (nv), each clamped to
    /// ±effort.
    pub fn continuous_torque(&self, t: f64, q: &[f64], v: &[f64], tau: &mut [f64]) {
        tau.iter_mut().for_each(|x| *x = 0.0);
        self.continuous_each(t, q, v, |c, raw, _| {
            tau[c.iv] += raw.clamp(-c.effort, c.effort)
        });
    }

    /// Continuous hold: the linear feedback of the controllers inside their effort at
    /// (t, q, v) — ∂τ/∂q = −k, ∂τ/∂v = −d and ∂τ/∂t = rate on each joint (a saturated one has
    /// none).
    pub fn continuous_feedback(&self, t: f64, q: &[f64], v: &[f64], mut f: impl FnMut(Feedback)) {
        self.continuous_each(t, q, v, |c, raw, (k, d, rate)| {
            if raw.abs() <= c.effort {
                f(Feedback {
                    iq: c.iq,
                    iv: c.iv,
                    k,
                    d,
                    integral: false,
                    rate,
                    saturated: false,
                });
            }
        });
    }

    /// Each controller with a target: its joint, raw (unclamped) torque at (t, q, v) and gains.
    fn continuous_each(
        &self,
        t: f64,
        q: &[f64],
        v: &[f64],
        mut f: impl FnMut(Joint, f64, (f64, f64, f64)),
    ) {
        let limits = self.wheel_limits(|_, c| self.raw(c, t, q, v));
        for (n, c) in self.velocity.iter().enumerate() {
            if !c.target.is_finite() {
                continue;
            }
            let raw = self.raw(c, t, q, v);
            let (target, target_rate) = self.target_at(c, t);
            // A frozen integral depends on neither q nor t; a lagged target moves either way.
            let (k, rate) = match c.frozen.is_nan() {
                true => (c.ki, c.ki * target + c.kp * target_rate),
                false => (0.0, c.kp * target_rate),
            };
            f(
                Joint {
                    iq: c.iq,
                    iv: c.iv,
                    effort: traction::effort(limits, n, c.effort),
                },
                raw,
                (k, c.kp, rate),
            );
        }
        for c in self.position.iter().filter(|c| c.target.is_finite()) {
            let raw = c.kp * (c.target - q[c.iq]) - c.kd * v[c.iv];
            f(
                Joint {
                    iq: c.iq,
                    iv: c.iv,
                    effort: c.effort,
                },
                raw,
                (c.kp, c.kd, 0.0),
            );
        }
    }

    /// Continuous hold: a velocity controller's raw (unclamped) torque at (t, q, v); 0 without
    /// a target.
    fn raw(&self, c: &Pi, t: f64, q: &[f64], v: &[f64]) -> f64 {
        match c.target.is_finite() {
            true => c.kp * (self.target_at(c, t).0 - v[c.iv]) + c.ki * self.integral(c, t, q),
            false => 0.0,
        }
    }

    /// Continuous hold: a velocity controller's target at t [rad/s or m/s] and its rate: the
    /// command's own, or under a lag the lagged one ([`lag`]).
    pub(super) fn target_at(&self, c: &Pi, t: f64) -> (f64, f64) {
        match c.lag_from.is_finite() {
            true => {
                let s = t - self.segment_start;
                let (from, to, tau) = (c.lag_from, c.target, self.lag_s);
                (lag::value(from, to, tau, s), lag::rate(from, to, tau, s))
            }
            false => (c.target, 0.0),
        }
    }

    /// Continuous hold: a velocity controller's integral ∫(v* − q̇) dt at (t, q) [rad or m] —
    /// held while frozen, else the exact integral less the skipped windup.
    fn integral(&self, c: &Pi, t: f64, q: &[f64]) -> f64 {
        if c.frozen.is_nan() {
            self.segment_integral(c, t, q) - c.windup
        } else {
            c.frozen
        }
    }

    /// ∫v* dt − (q − q(0)) at (t, q): the integral without anti-windup [rad or m].
    fn segment_integral(&self, c: &Pi, t: f64, q: &[f64]) -> f64 {
        let s = t - self.segment_start;
        let target = match c.lag_from.is_finite() {
            true => lag::integral(c.lag_from, c.target, self.lag_s, s),
            false => c.target * s,
        };
        c.target_integral + target - (q[c.iq] - c.q_start)
    }

    /// Continuous hold, anti-windup at (t, q, v), between steps: a velocity controller beyond
    /// its effort freezes its integral, a frozen one back inside resumes integrating from the
    /// value it held (its skipped error integral joins `windup`). True when one changed: the
    /// right-hand side is then another function (an implicit method's F is stale).
    pub fn review_saturation(&mut self, t: f64, q: &[f64], v: &[f64]) -> bool {
        let mut changed = false;
        let limits = self.wheel_limits(|_, c| self.raw(c, t, q, v));
        for k in 0..self.velocity.len() {
            let c = &self.velocity[k];
            if !c.target.is_finite() {
                continue;
            }
            let effort = traction::effort(limits, k, c.effort);
            let integral = self.integral(c, t, q);
            let raw = c.kp * (self.target_at(c, t).0 - v[c.iv]) + c.ki * integral;
            let frozen = c.frozen.is_finite();
            let free = self.segment_integral(c, t, q) - c.windup;
            let c = &mut self.velocity[k];
            if !frozen && raw.abs() > effort {
                (c.frozen, c.gain) = (integral, (0.0, 0.0));
                changed = true;
            } else if frozen && raw.abs() <= effort {
                c.windup += free - c.frozen;
                (c.frozen, c.gain) = (f64::NAN, (c.ki, c.kp));
                changed = true;
            }
        }
        changed
    }

    /// True while a velocity controller with a target holds its integral.
    pub fn any_frozen(&self) -> bool {
        (self.velocity.iter()).any(|c| c.target.is_finite() && c.frozen.is_finite())
    }

    /// Continuous hold: from (t, q, v, q̈) at a span's start, the shortest time [s] after which
    /// a frozen controller's torque, moving at its rate kp (ṫarget − q̈) (its integral held),
    /// comes back inside its effort (a coupled traction limit held at the span's start's);
    /// None when none is heading back.
    pub fn saturation_exit(&self, t: f64, q: &[f64], v: &[f64], qdd: &[f64]) -> Option<f64> {
        let limits = self.wheel_limits(|_, c| self.raw(c, t, q, v));
        self.velocity
            .iter()
            .enumerate()
            .filter(|(_, c)| c.target.is_finite() && c.frozen.is_finite())
            .filter_map(|(k, c)| {
                let (target, target_rate) = self.target_at(c, t);
                let raw = c.kp * (target - v[c.iv]) + c.ki * c.frozen;
                let rate = c.kp * (target_rate - qdd[c.iv]);
                let excess = raw.abs() - traction::effort(limits, k, c.effort);
                let toward = -rate * raw.signum();
                (excess > 0.0 && toward > 0.0).then(|| excess / toward)
            })
            .min_by(f64::total_cmp)
    }
}

/// A controlled joint's indices and effort bound.
#[derive(Clone, Copy)]
struct Joint {
    iq: usize,
    iv: usize,
    effort: f64,
}
