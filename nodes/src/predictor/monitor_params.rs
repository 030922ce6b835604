//! `monitor.*`: how the predictor scores its own past predictions against the odometry and
//! joint states that arrive (`~/prediction_residuals`, `/diagnostics`, a WARN naming the likely
//! cause). Fixed while the node runs.

use serde::{Deserialize, Serialize};

use constraint_dynamics::monitor::{MonitorSettings, Thresholds};

use crate::params::{ParamsError, positive};

/// The most horizons scored, and the longest window: bound the monitor's memory and work.
pub const MAX_HORIZONS: usize = 16;
pub const MAX_WINDOW: u32 = 10_000;

/// `monitor.*` (see the module's documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MonitorParams {
    /// Score the predictions, publish `~/prediction_residuals` and WARN on a mismatch.
    pub enabled: bool,
    /// The horizons scored [s] (each > 0; those beyond the prediction's horizon are skipped).
    pub horizons: Vec<f64>,
    /// Samples per statistic window (per horizon; [1, 10000]).
    pub window: u32,
    /// Samples a window needs before a cause is called ([1, window]).
    pub min_samples: u32,
    /// The latest a measurement may arrive after a prediction's due time and still be its
    /// measurement [s] (> 0).
    pub max_lag: f64,
    /// Median NEES of (x, y, yaw) above which the odometry is called off the model, and the
    /// mean NEES above which a lag is called (> 0; χ²₃'s median is 2.37, its mean 3).
    pub nees_threshold: f64,
    /// |Median effort error| of a joint above which its efforts are called off [N·m or N] (> 0).
    pub effort_threshold: f64,
    /// Measured start states (one per tick) whose velocity residual off the constraints the
    /// slip statistic takes the median of ([1, 10000]).
    pub slip_window: u32,
    /// The measured states' median velocity residual off the constraints (‖J v‖ before the
    /// projection: a rolling wheel's surface speed against the base's measured motion) above
    /// which the wheels are called slipping [m/s or rad/s] (> 0).
    pub slip_threshold: f64,
    /// The lag [s] beyond which the drive is called late: its pose errors follow the gap
    /// between each start's velocity and its command, closed this much later than the model
    /// closes it (> 0; with three standard errors and a mean NEES above `nees_threshold`).
    pub lag_threshold: f64,
    /// A called cause clears below this fraction of its threshold (in (0, 1]).
    pub clear_ratio: f64,
    /// A command whose v [m/s] or ω [rad/s] moves off the last by more than this changes what
    /// the pending predictions assumed: they are not scored ([v, ω], each ≥ 0).
    pub command_tolerance: Vec<f64>,
    /// The model error a prediction's covariance is widened by: σ per metre travelled [m/m]
    /// on x and y and per radian turned [rad/rad] on yaw, over each horizon ([translation,
    /// rotation], each ≥ 0).
    pub motion_error: Vec<f64>,
}

impl Default for MonitorParams {
    fn default() -> Self {
        MonitorParams {
            enabled: true,
            horizons: vec![0.25, 0.5, 1.0],
            window: 50,
            min_samples: 20,
            max_lag: 0.1,
            nees_threshold: 9.0,
            effort_threshold: 2.0,
            slip_window: 10,
            slip_threshold: 0.05,
            lag_threshold: 0.08,
            clear_ratio: 0.5,
            command_tolerance: vec![0.005, 0.01],
            motion_error: vec![0.02, 0.05],
        }
    }
}

impl MonitorParams {
    /// Checks every value, naming the one that is wrong.
    pub fn validate(&self) -> Result<(), ParamsError> {
        let h = &self.horizons;
        if h.is_empty() || h.len() > MAX_HORIZONS || h.iter().any(|x| !(x.is_finite() && *x > 0.0))
        {
            return Err(ParamsError::invalid(
                "monitor.horizons",
                format!("= {h:?} must be 1 to {MAX_HORIZONS} positive finite times [s]"),
            ));
        }
        if !(1..=MAX_WINDOW).contains(&self.window) {
            return Err(ParamsError::invalid(
                "monitor.window",
                format!("= {} must be in [1, {MAX_WINDOW}]", self.window),
            ));
        }
        if !(1..=self.window).contains(&self.min_samples) {
            return Err(ParamsError::invalid(
                "monitor.min_samples",
                format!("= {} must be in [1, monitor.window]", self.min_samples),
            ));
        }
        positive("monitor.max_lag", self.max_lag)?;
        positive("monitor.nees_threshold", self.nees_threshold)?;
        positive("monitor.effort_threshold", self.effort_threshold)?;
        if !(1..=MAX_WINDOW).contains(&self.slip_window) {
            return Err(ParamsError::invalid(
                "monitor.slip_window",
                format!("= {} must be in [1, {MAX_WINDOW}]", self.slip_window),
            ));
        }
        positive("monitor.slip_threshold", self.slip_threshold)?;
        positive("monitor.lag_threshold", self.lag_threshold)?;
        let pair = |name: &str, x: &[f64], what: &str| match x.len() == 2
            && x.iter().all(|x| x.is_finite() && *x >= 0.0)
        {
            true => Ok(()),
            false => Err(ParamsError::invalid(
                name,
                format!("= {x:?} must be {what}, finite and ≥ 0"),
            )),
        };
        pair(
            "monitor.command_tolerance",
            &self.command_tolerance,
            "[v [m/s], ω [rad/s]]",
        )?;
        pair(
            "monitor.motion_error",
            &self.motion_error,
            "[per metre [m/m], per radian [rad/rad]]",
        )?;
        let c = self.clear_ratio;
        if !(c > 0.0 && c <= 1.0) {
            return Err(ParamsError::invalid(
                "monitor.clear_ratio",
                format!("= {c} must be in (0, 1]"),
            ));
        }
        Ok(())
    }

    /// The command tolerance [v [m/s], ω [rad/s]] (validated: two values).
    pub fn command_tolerance(&self) -> [f64; 2] {
        pair(&self.command_tolerance)
    }

    /// The model error per metre travelled and per radian turned (validated: two values).
    pub fn motion_error(&self) -> [f64; 2] {
        pair(&self.motion_error)
    }

    /// The core's settings, for predictions at `rate` [Hz].
    pub fn settings(&self, rate: f64) -> MonitorSettings {
        let longest = self.horizons.iter().copied().fold(0.0, f64::max);
        MonitorSettings {
            horizons: self.horizons.clone(),
            window: self.window as usize,
            // Every prediction pending until its measurement, with room for a late one.
            pending: ((longest + self.max_lag) * rate).ceil().clamp(1.0, 1e5) as usize + 2,
            max_lag: self.max_lag,
            slip_window: self.slip_window as usize,
            thresholds: Thresholds {
                min_samples: self.min_samples as usize,
                nees: self.nees_threshold,
                effort: self.effort_threshold,
                slip: self.slip_threshold,
                lag: self.lag_threshold,
                clear_ratio: self.clear_ratio,
            },
        }
    }
}

fn pair(x: &[f64]) -> [f64; 2] {
    [x.first(), x.get(1)].map(|x| x.copied().unwrap_or(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_values_are_named() {
        let bad = |p: MonitorParams, name: &str| {
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        };
        let d = MonitorParams::default();
        assert!(d.validate().is_ok());
        bad(
            MonitorParams {
                horizons: vec![0.5, -1.0],
                ..d.clone()
            },
            "monitor.horizons",
        );
        bad(
            MonitorParams {
                horizons: vec![],
                ..d.clone()
            },
            "monitor.horizons",
        );
        bad(
            MonitorParams {
                window: 0,
                ..d.clone()
            },
            "monitor.window",
        );
        bad(
            MonitorParams {
                min_samples: 51,
                ..d.clone()
            },
            "monitor.min_samples",
        );
        bad(
            MonitorParams {
                clear_ratio: 0.0,
                ..d.clone()
            },
            "monitor.clear_ratio",
        );
        bad(
            MonitorParams {
                command_tolerance: vec![0.01, -1.0],
                ..d.clone()
            },
            "monitor.command_tolerance",
        );
        bad(
            MonitorParams {
                motion_error: vec![0.02],
                ..d.clone()
            },
            "monitor.motion_error",
        );
        bad(
            MonitorParams {
                nees_threshold: f64::NAN,
                ..d.clone()
            },
            "monitor.nees_threshold",
        );
        // 1 s + 0.1 s at 10 Hz: 11 pending, and 2 spare.
        assert_eq!(d.settings(10.0).pending, 13);
    }
}
