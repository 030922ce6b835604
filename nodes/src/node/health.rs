//! A node's health, as `diagnostic_msgs/DiagnosticStatus`: what it was asked to do against what
//! it does (tick rate, compute time), the age of its inputs, and its last error — the concerns
//! diagnostic_updater's `FrequencyStatus` and `TimeStampStatus` cover, on the ROS clock.
//!
//! Levels: ERROR when the node cannot do its periodic work (the last tick failed); WARN when an
//! input it subscribes to is older than `diagnostics.input_timeout` (or never came) or the tick
//! rate is below `diagnostics.min_rate_fraction` of the requested one; OK otherwise.

use std::collections::VecDeque;

use crate::msg::builtin_interfaces::Time;
use crate::msg::diagnostic_msgs::{DiagnosticStatus, KeyValue};
use crate::params::DiagnosticsParams;

/// How many recent compute times and ticks the statistics cover.
const WINDOW: usize = 100;

/// An input every node may subscribe to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// `joint_states`.
    JointStates,
    /// `odom`.
    Odometry,
}

/// What the status is about, besides what [`Health`] recorded.
pub struct StatusContext<'a> {
    /// The node's fully qualified name (the status' `name`).
    pub name: &'a str,
    /// The robot model (the status' `hardware_id`).
    pub model: &'a str,
    /// The requested tick rate [Hz], for kinds that tick.
    pub requested_rate: Option<f64>,
    /// Which inputs the node subscribes to.
    pub subscribed: &'a [Input],
    /// Thresholds.
    pub params: &'a DiagnosticsParams,
    /// Kind-specific values (slipping contacts, residuals).
    pub extra: Vec<KeyValue>,
    /// Kind-specific reasons for a WARN (the predictor's stale inputs).
    pub warnings: Vec<String>,
    /// The kind's reason for a rate below the requested one, if it knows one (the predictor's
    /// tick longer than its period), appended to the rate warning.
    pub rate_shortfall: Option<String>,
}

/// What a worker records of its node's work.
#[derive(Clone, Debug, Default)]
pub struct Health {
    ticks: VecDeque<Time>,
    compute_ms: VecDeque<f64>,
    joint_states_at: Option<Time>,
    odom_at: Option<Time>,
    served: u64,
    tick_failing: bool,
    last_error: Option<String>,
}

fn secs(a: Time, b: Time) -> f64 {
    (a.to_nanos() - b.to_nanos()) as f64 * 1e-9
}

fn push<T>(q: &mut VecDeque<T>, x: T) {
    if q.len() == WINDOW {
        q.pop_front();
    }
    q.push_back(x);
}

impl Health {
    /// An input message arrived (and was used) at ROS time `now`.
    pub fn input(&mut self, which: Input, now: Time) {
        match which {
            Input::JointStates => self.joint_states_at = Some(now),
            Input::Odometry => self.odom_at = Some(now),
        }
    }

    /// A periodic tick at ROS time `now` took `compute_s` [s]; `error` if it failed.
    pub fn tick(&mut self, now: Time, compute_s: f64, error: Option<String>) {
        push(&mut self.ticks, now);
        push(&mut self.compute_ms, compute_s * 1e3);
        self.tick_failing = error.is_some();
        if error.is_some() {
            self.last_error = error;
        }
    }

    /// A request was served in `compute_s` [s].
    pub fn request(&mut self, compute_s: f64) {
        self.served += 1;
        push(&mut self.compute_ms, compute_s * 1e3);
    }

    /// An error worth reporting (a refused model, a dropped message).
    pub fn error(&mut self, message: String) {
        self.last_error = Some(message);
    }

    /// Achieved tick rate over the recent ticks [Hz] (None before two ticks).
    pub fn achieved_rate(&self) -> Option<f64> {
        let (first, last) = (self.ticks.front()?, self.ticks.back()?);
        let span = secs(*last, *first);
        (self.ticks.len() >= 2 && span > 0.0).then(|| (self.ticks.len() - 1) as f64 / span)
    }

    /// The achieved rate [Hz] when it is below `params.min_rate_fraction` of `requested`.
    fn low_rate(&self, requested: f64, params: &DiagnosticsParams) -> Option<f64> {
        self.achieved_rate()
            .filter(|r| *r < params.min_rate_fraction * requested)
    }

    /// The age of `input` at ROS time `now` [s], None before it first arrived.
    fn input_age(&self, input: Input, now: Time) -> Option<f64> {
        let at = match input {
            Input::JointStates => self.joint_states_at,
            Input::Odometry => self.odom_at,
        };
        at.map(|t| secs(now, t))
    }

    /// The level [`Self::status`] gives at ROS time `now` (with `kind_warns` for a kind's own
    /// warnings), without building its values and messages: a worker asks after every event
    /// whether the level changed, and builds the status only when it did or one is due.
    pub fn level(
        &self,
        now: Time,
        requested_rate: Option<f64>,
        subscribed: &[Input],
        params: &DiagnosticsParams,
        kind_warns: bool,
    ) -> u8 {
        let stale = |i: &Input| {
            self.input_age(*i, now)
                .is_none_or(|a| a > params.input_timeout)
        };
        if self.tick_failing {
            DiagnosticStatus::ERROR
        } else if kind_warns
            || requested_rate.is_some_and(|r| self.low_rate(r, params).is_some())
            || subscribed.iter().any(stale)
        {
            DiagnosticStatus::WARN
        } else {
            DiagnosticStatus::OK
        }
    }

    /// The status at ROS time `now`.
    pub fn status(&self, now: Time, ctx: StatusContext) -> DiagnosticStatus {
        let mut values = vec![kv("model", ctx.model)];
        let mut warnings = ctx.warnings;
        if let Some(requested) = ctx.requested_rate {
            values.push(kv("requested rate [Hz]", &format!("{requested:.3}")));
            match self.achieved_rate() {
                Some(r) => values.push(kv("achieved rate [Hz]", &format!("{r:.3}"))),
                None => values.push(kv("achieved rate [Hz]", "-")),
            }
            if let Some(r) = self.low_rate(requested, ctx.params) {
                let why = match &ctx.rate_shortfall {
                    Some(why) => format!(": {why}"),
                    None => String::new(),
                };
                warnings.push(format!("rate {r:.2} Hz < requested {requested} Hz{why}"));
            }
        }
        if !self.compute_ms.is_empty() {
            let mut sorted: Vec<f64> = self.compute_ms.iter().copied().collect();
            sorted.sort_by(f64::total_cmp);
            values.push(kv(
                "compute p50 [ms]",
                &format!("{:.3}", sorted[sorted.len() / 2]),
            ));
            values.push(kv(
                "compute max [ms]",
                &format!("{:.3}", sorted[sorted.len() - 1]),
            ));
        }
        for &input in ctx.subscribed {
            let name = match input {
                Input::JointStates => "joint_states",
                Input::Odometry => "odom",
            };
            match self.input_age(input, now) {
                Some(age) => {
                    values.push(kv(&format!("{name} age [s]"), &format!("{age:.3}")));
                    if age > ctx.params.input_timeout {
                        warnings.push(format!("{name} stale ({age:.1} s old)"));
                    }
                }
                None => {
                    values.push(kv(&format!("{name} age [s]"), "never received"));
                    warnings.push(format!("no {name} received"));
                }
            }
        }
        values.push(kv("requests served", &self.served.to_string()));
        values.extend(ctx.extra);
        values.push(kv("last error", self.last_error.as_deref().unwrap_or("")));
        let (level, message) = if self.tick_failing {
            let e = self
                .last_error
                .as_deref()
                .unwrap_or("the last prediction failed");
            (DiagnosticStatus::ERROR, format!("cannot predict: {e}"))
        } else if !warnings.is_empty() {
            (DiagnosticStatus::WARN, warnings.join("; "))
        } else {
            (DiagnosticStatus::OK, "ok".to_string())
        };
        DiagnosticStatus {
            level,
            name: ctx.name.to_string(),
            message,
            hardware_id: ctx.model.to_string(),
            values,
        }
    }
}

/// A key–value pair.
pub fn kv(key: &str, value: &str) -> KeyValue {
    KeyValue {
        key: key.to_string(),
        value: value.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctx<'a>(params: &'a DiagnosticsParams, subscribed: &'a [Input]) -> StatusContext<'a> {
        StatusContext {
            name: "/robot1/cd_predictor",
            model: "diff_drive",
            requested_rate: Some(10.0),
            subscribed,
            params,
            extra: vec![],
            warnings: vec![],
            rate_shortfall: None,
        }
    }

    fn at(s: f64) -> Time {
        Time::from_nanos((s * 1e9) as i64)
    }

    #[test]
    fn ok_then_warn_when_odometry_stops_then_error_when_prediction_fails() {
        let p = DiagnosticsParams::default();
        let subs = [Input::Odometry];
        let mut h = Health::default();
        // Ticks at 10 Hz with odometry at each: OK, achieved rate 10 Hz.
        for k in 0..20 {
            h.input(Input::Odometry, at(0.1 * k as f64));
            h.tick(at(0.1 * k as f64), 0.002, None);
        }
        let s = h.status(at(1.95), ctx(&p, &subs));
        assert_eq!(s.level, DiagnosticStatus::OK, "{s:?}");
        let rate = s
            .values
            .iter()
            .find(|v| v.key == "achieved rate [Hz]")
            .unwrap();
        assert_eq!(rate.value, "10.000");
        // Odometry stops: 1.2 s later (> input_timeout = 1 s) it is stale.
        let s = h.status(at(3.1), ctx(&p, &subs));
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert!(s.message.contains("odom stale"), "{}", s.message);
        // A failed tick is an ERROR naming the reason.
        h.tick(at(3.2), 0.001, Some("prediction: step size".into()));
        let s = h.status(at(3.2), ctx(&p, &subs));
        assert_eq!(s.level, DiagnosticStatus::ERROR);
        assert!(s.message.contains("step size"), "{}", s.message);
    }

    /// A kind's own warning (the predictor's stale inputs) makes the status WARN with it.
    #[test]
    fn a_kind_warning_is_a_warn() {
        let p = DiagnosticsParams::default();
        let mut h = Health::default();
        for k in 0..5 {
            h.input(Input::Odometry, at(0.1 * k as f64));
            h.tick(at(0.1 * k as f64), 0.001, None);
        }
        let mut c = ctx(&p, &[Input::Odometry]);
        c.warnings = vec!["odom stale (odom 0.62 s > state.timeout 0.5 s)".into()];
        let s = h.status(at(0.45), c);
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert_eq!(s.message, "odom stale (odom 0.62 s > state.timeout 0.5 s)");
    }

    #[test]
    fn missed_rate_and_missing_input_warn() {
        let p = DiagnosticsParams::default();
        let mut h = Health::default();
        for k in 0..5 {
            h.tick(at(0.2 * k as f64), 0.15, None); // 5 Hz against 10 requested
        }
        let s = h.status(at(0.8), ctx(&p, &[Input::JointStates]));
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert!(
            s.message.contains("rate 5.00 Hz < requested 10 Hz"),
            "{}",
            s.message
        );
        assert!(
            s.message.contains("no joint_states received"),
            "{}",
            s.message
        );
        let p50 = s
            .values
            .iter()
            .find(|v| v.key == "compute p50 [ms]")
            .unwrap();
        assert_eq!(p50.value, "150.000");
    }

    /// The level a worker checks after every event is the one the status would give: OK,
    /// each reason for a WARN alone, and a failed tick's ERROR.
    #[test]
    fn the_level_is_the_status_level() {
        let p = DiagnosticsParams::default();
        let subs = [Input::Odometry, Input::JointStates];
        let check = |h: &Health, t: f64, kind: bool, want: u8| {
            let mut c = ctx(&p, &subs);
            if kind {
                c.warnings = vec!["odom stale (odom 0.62 s > state.timeout 0.5 s)".into()];
            }
            let s = h.status(at(t), c);
            assert_eq!(s.level, want, "{s:?}");
            assert_eq!(h.level(at(t), Some(10.0), &subs, &p, kind), want);
        };
        let mut h = Health::default();
        check(&h, 0.0, false, DiagnosticStatus::WARN); // nothing received yet
        for k in 0..20 {
            h.input(Input::Odometry, at(0.1 * k as f64));
            h.input(Input::JointStates, at(0.1 * k as f64));
            h.tick(at(0.1 * k as f64), 0.002, None);
        }
        check(&h, 1.95, false, DiagnosticStatus::OK);
        check(&h, 1.95, true, DiagnosticStatus::WARN); // the kind's own warning
        check(&h, 3.1, false, DiagnosticStatus::WARN); // stale inputs (and a low rate)
        let mut slow = Health::default();
        for k in 0..5 {
            slow.input(Input::Odometry, at(0.8));
            slow.input(Input::JointStates, at(0.8));
            slow.tick(at(0.2 * k as f64), 0.15, None); // 5 Hz against 10 requested
        }
        check(&slow, 0.8, false, DiagnosticStatus::WARN);
        h.tick(at(2.0), 0.001, Some("prediction: step size".into()));
        check(&h, 2.0, false, DiagnosticStatus::ERROR);
    }

    /// The kind's reason for a low rate joins the rate warning, and only when the rate is low.
    #[test]
    fn a_low_rate_carries_the_kinds_reason() {
        let p = DiagnosticsParams::default();
        let why = "a tick takes 150 ms ≥ the 100 ms period".to_string();
        let mut slow = Health::default();
        let mut on_time = Health::default();
        for k in 0..5 {
            slow.tick(at(0.2 * k as f64), 0.15, None);
            on_time.tick(at(0.1 * k as f64), 0.15, None);
        }
        let mut c = ctx(&p, &[]);
        c.rate_shortfall = Some(why.clone());
        let s = slow.status(at(0.8), c);
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert_eq!(s.message, format!("rate 5.00 Hz < requested 10 Hz: {why}"));
        let mut c = ctx(&p, &[]);
        c.rate_shortfall = Some(why);
        let s = on_time.status(at(0.4), c);
        assert_eq!(s.level, DiagnosticStatus::OK, "{}", s.message);
    }
}
