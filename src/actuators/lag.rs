//! `actuators.diff_drive.command_lag: τ`: the drive follows its commanded (v, ω) through a
//! first-order lag, ẋ = (u − x)/τ, before its wheel controllers see it — the velocity loop of a
//! motor controller, or a drive's own smoothing, that the scene does not model. Under a
//! piecewise-constant command u the lagged target is exact in closed form, so neither hold
//! adds a state to the integration: the held controllers advance it tick by tick, the
//! continuous ones read it (and its integral) at any time of a command segment.
//!
//! The lag's state at a prediction's start is not in the robot's state: it is what the
//! commands before the start left ([`CommandLag`] over their history, as the predictor node and
//! the replay keep it), the start's wheel speeds (a request without a history:
//! [`super::Actuators::drive_command_of_wheels`]), or the first command's (the drive long at
//! rest on it).

/// The shortest lag [s] that is one: a shorter one (a calibrated value at the edge of 0) is the
/// command itself, so that the lag's rate, (u − x)/τ, stays finite.
pub const MIN_LAG_S: f64 = 1e-6;

/// The lagged target `s` [s] into a segment that started at `from` under the target `to`.
pub(super) fn value(from: f64, to: f64, tau: f64, s: f64) -> f64 {
    to + (from - to) * (-s / tau).exp()
}

/// ∫₀ˢ of [`value`] [target × s].
pub(super) fn integral(from: f64, to: f64, tau: f64, s: f64) -> f64 {
    to * s - (from - to) * tau * (-s / tau).exp_m1()
}

/// d/ds of [`value`] [target / s].
pub(super) fn rate(from: f64, to: f64, tau: f64, s: f64) -> f64 {
    (to - value(from, to, tau, s)) / tau
}

/// A drive's lagged command (v [m/s], ω [rad/s]) over a stream of commands, each in force
/// from its time until the next (what a prediction's start needs: [`CommandLag::at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandLag {
    /// τ [s].
    tau_s: f64,
    /// The time [s] the lagged value is at, the command in force from then on, and the lagged
    /// value; None before the first command.
    state: Option<(f64, [f64; 2], [f64; 2])>,
}

impl CommandLag {
    /// A lag of time constant `tau_s` [s] (below [`MIN_LAG_S`]: none, the command itself), no
    /// command yet.
    pub fn new(tau_s: f64) -> Self {
        let tau_s = if tau_s >= MIN_LAG_S { tau_s } else { 0.0 };
        Self { tau_s, state: None }
    }

    /// `command` in force from `t` [s] on. The first command is taken as long in force (the
    /// lagged value starts on it); a time before the last one (a simulation's clock started
    /// again) restarts the lag's clock there, its lagged value kept.
    pub fn push(&mut self, t: f64, command: [f64; 2]) {
        let lagged = self.at(t).unwrap_or(command);
        self.state = Some((t, command, lagged));
    }

    /// The lagged command at `t` [s] (at or after the last push's time; earlier counts as
    /// that time); None before the first command.
    pub fn at(&self, t: f64) -> Option<[f64; 2]> {
        let (t_last, command, lagged) = self.state?;
        if self.tau_s <= 0.0 {
            return Some(command);
        }
        let s = (t - t_last).max(0.0);
        Some([0, 1].map(|i| value(lagged[i], command[i], self.tau_s, s)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed forms against a fine forward-Euler integration of ẋ = (u − x)/τ.
    #[test]
    fn the_closed_forms_integrate_the_lag() {
        let (from, to, tau, s_end) = (0.3, -1.1, 0.15, 0.4);
        let n = 400_000;
        let h = s_end / n as f64;
        let (mut x, mut area) = (from, 0.0);
        for _ in 0..n {
            area += h * x;
            x += h * (to - x) / tau;
        }
        assert!((value(from, to, tau, s_end) - x).abs() < 1e-5);
        assert!((integral(from, to, tau, s_end) - area).abs() < 1e-5);
        let d = 1e-6;
        let fd = (value(from, to, tau, s_end + d) - value(from, to, tau, s_end - d)) / (2.0 * d);
        assert!((rate(from, to, tau, s_end) - fd).abs() < 1e-8);
    }

    /// A step from rest reaches 1 − e⁻¹ of the command after τ; a second command continues
    /// from where the first left the lag.
    #[test]
    fn a_command_stream_lags_by_tau() {
        let mut lag = CommandLag::new(0.2);
        assert_eq!(lag.at(0.0), None);
        lag.push(0.0, [0.0, 0.0]);
        lag.push(1.0, [1.0, -2.0]);
        let after_tau = lag.at(1.2).unwrap();
        let reached = 1.0 - (-1.0f64).exp();
        assert!((after_tau[0] - reached).abs() < 1e-15);
        assert!((after_tau[1] + 2.0 * reached).abs() < 1e-15);
        lag.push(1.2, [0.0, 0.0]);
        let later = lag.at(1.4).unwrap();
        assert!((later[0] - reached * (-1.0f64).exp()).abs() < 1e-15);
        assert_eq!(CommandLag::new(0.0).at(0.0), None);
        let mut none = CommandLag::new(0.0);
        none.push(0.0, [0.5, 0.1]);
        none.push(0.1, [1.0, 0.0]);
        assert_eq!(none.at(0.1), Some([1.0, 0.0]));
        // A clock that starts again (a looped log's /clock) restarts the lag there.
        let mut looped = CommandLag::new(0.2);
        looped.push(10.0, [1.0, 0.0]);
        looped.push(0.0, [0.0, 0.0]);
        let decayed = looped.at(0.2).unwrap();
        assert!((decayed[0] - (-1.0f64).exp()).abs() < 1e-15);
        // Below a microsecond a lag is none: its rate (u − x)/τ would overflow.
        let mut tiny = CommandLag::new(1e-300);
        tiny.push(0.0, [0.5, 0.1]);
        tiny.push(0.1, [1.0, 0.0]);
        assert_eq!(tiny.at(0.1), Some([1.0, 0.0]));
    }
}
