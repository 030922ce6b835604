//! What the velocity smoother bridge sends: Nav2's velocity smoother's `max_accel` and
//! `max_decel` ([x, y, θ] doubles, decelerations negative) from one acceleration envelope, and
//! when a new value is worth sending. No ROS here: [`super::smoother_ros`] calls the services.
//!
//! The smoother limits the change of |v| per axis: `max_accel` while the speed grows,
//! `max_decel` while it shrinks or passes through 0. The envelope's limits are signed along the
//! base's forward axis, so which one bounds which smoother value depends on the direction of
//! motion (the base's forward speed at the envelope's state):
//!
//! | motion | max_accel[0] | −max_decel[0] |
//! |---|---|---|
//! | forward (v_x > [`REST_SPEED`]) | forward acceleration | forward deceleration |
//! | reversing (v_x < −[`REST_SPEED`]) | forward deceleration | forward acceleration |
//! | at rest | the smaller of the two | the smaller of the two |
//!
//! θ takes the smaller of the two yaw limits, both ways. y is the smoother's own (the envelope
//! says nothing of lateral motion). Every value is capped at the smoother's own setting read
//! at the start (the envelope is what the robot can do, the setting what it should do); an
//! unbounded limit leaves the setting; a limit at or below the floor (≤ 0: the robot cannot
//! even hold that direction's acceleration at 0 with every contact holding; infeasible) is
//! sent as the floor, the gentlest value a smoother accepts (`max_accel > 0`, `max_decel < 0`).

use std::time::{Duration, Instant};

use crate::msg::constraint_dynamics_msgs::{AccelerationLimit, AccelerationLimits};

use super::params::EnvelopeParams;

/// Below this forward speed [m/s] the base counts as at rest (either direction may follow).
pub const REST_SPEED: f64 = 0.01;

/// A smoother's `max_accel` (> 0) and `max_decel` (< 0), [x m/s², y m/s², θ rad/s²].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmootherLimits {
    /// `max_accel`.
    pub max_accel: [f64; 3],
    /// `max_decel` (negative).
    pub max_decel: [f64; 3],
}

impl SmootherLimits {
    /// Checks what a smoother's parameters hold: three finite values each, `max_accel` > 0 and
    /// `max_decel` < 0 on x and θ (y may be 0 on a differential drive).
    pub fn from_setting(accel: &[f64], decel: &[f64]) -> Result<Self, String> {
        let three = |name: &str, x: &[f64]| -> Result<[f64; 3], String> {
            match x {
                [a, b, c] if x.iter().all(|v| v.is_finite()) => Ok([*a, *b, *c]),
                _ => Err(format!(
                    "{name} = {x:?} is not three finite doubles [x, y, θ]"
                )),
            }
        };
        let (a, d) = (three("max_accel", accel)?, three("max_decel", decel)?);
        if a[0] <= 0.0 || a[2] <= 0.0 || a[1] < 0.0 || d[0] >= 0.0 || d[2] >= 0.0 || d[1] > 0.0 {
            return Err(format!(
                "max_accel = {a:?} must be positive and max_decel = {d:?} negative (x, θ)"
            ));
        }
        Ok(SmootherLimits {
            max_accel: a,
            max_decel: d,
        })
    }

    fn values(&self) -> [f64; 6] {
        let (a, d) = (self.max_accel, self.max_decel);
        [a[0], a[1], a[2], d[0], d[1], d[2]]
    }
}

/// The values to send for `limits` at forward speed `v_x` [m/s], given the smoother's own
/// setting; and a note for each limit sent at its floor.
pub fn smoother_limits(
    limits: &AccelerationLimits,
    v_x: f64,
    setting: &SmootherLimits,
    p: &EnvelopeParams,
) -> (SmootherLimits, Vec<String>) {
    let mut floored = Vec::new();
    // One limit as a magnitude for a smoother value capped at `cap`.
    let mut value = |name: &str, l: &AccelerationLimit, floor: f64, cap: f64| -> f64 {
        let v = match l.status {
            AccelerationLimit::UNBOUNDED => return cap,
            AccelerationLimit::BOUNDED if l.max > floor => l.max,
            _ => {
                let what = match l.status {
                    AccelerationLimit::BOUNDED => format!("{:.4}", l.max),
                    _ => "infeasible".to_string(),
                };
                floored.push(format!("{name} {what} sent as {floor}"));
                floor
            }
        };
        v.min(cap)
    };
    let (s_a, s_d) = (setting.max_accel, setting.max_decel);
    let (fa, fd) = (&limits.forward_acceleration, &limits.forward_deceleration);
    let (lf, af) = (p.linear_floor, p.angular_floor);
    let (cap_ax, cap_dx) = (s_a[0], -s_d[0]);
    let (accel_x, decel_x) = if v_x > REST_SPEED {
        (
            value("forward acceleration", fa, lf, cap_ax),
            value("forward deceleration", fd, lf, cap_dx),
        )
    } else if v_x < -REST_SPEED {
        (
            value("forward deceleration", fd, lf, cap_ax),
            value("forward acceleration", fa, lf, cap_dx),
        )
    } else {
        let a = value("forward acceleration", fa, lf, f64::INFINITY);
        let d = value("forward deceleration", fd, lf, f64::INFINITY);
        (a.min(d).min(cap_ax), a.min(d).min(cap_dx))
    };
    let yaw = |value: &mut dyn FnMut(&str, &AccelerationLimit, f64, f64) -> f64, cap: f64| {
        let l = value(
            "yaw acceleration left",
            &limits.yaw_acceleration_left,
            af,
            cap,
        );
        let r = value(
            "yaw acceleration right",
            &limits.yaw_acceleration_right,
            af,
            cap,
        );
        l.min(r)
    };
    let accel_yaw = yaw(&mut value, s_a[2]);
    let decel_yaw = yaw(&mut value, -s_d[2]);
    floored.dedup();
    let out = SmootherLimits {
        max_accel: [accel_x, s_a[1], accel_yaw],
        max_decel: [-decel_x, s_d[1], -decel_yaw],
    };
    (out, floored)
}

/// The dead band: what was last sent and when.
#[derive(Clone, Debug, Default)]
pub struct DeadBand {
    sent: Option<(SmootherLimits, Instant)>,
}

impl DeadBand {
    /// Whether `next` should be sent at `now`: the first time; at once when a value tightens
    /// (its magnitude falls) by more than `dead_band` of the sent one; when values only loosen by
    /// more than that, once `min_interval` has passed since the last send.
    pub fn due(
        &self,
        next: &SmootherLimits,
        now: Instant,
        dead_band: f64,
        min_interval: Duration,
    ) -> bool {
        let Some((sent, at)) = &self.sent else {
            return true;
        };
        let pairs = sent.values().into_iter().zip(next.values());
        let mut loosens = false;
        for (s, n) in pairs {
            let band = dead_band * s.abs();
            if n.abs() < s.abs() - band {
                return true;
            }
            loosens |= n.abs() > s.abs() + band;
        }
        loosens && now.saturating_duration_since(*at) >= min_interval
    }

    /// Records a successful send.
    pub fn sent(&mut self, limits: SmootherLimits, now: Instant) {
        self.sent = Some((limits, now));
    }
}

#[cfg(test)]
#[path = "smoother_tests.rs"]
mod tests;
