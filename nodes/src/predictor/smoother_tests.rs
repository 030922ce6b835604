//! The bridge's mapping and dead band on hand-made envelopes.

use std::time::{Duration, Instant};

use super::*;

fn bounded(max: f64) -> AccelerationLimit {
    AccelerationLimit {
        status: AccelerationLimit::BOUNDED,
        max,
        ..Default::default()
    }
}

fn limits(fa: f64, fd: f64, yl: f64, yr: f64) -> AccelerationLimits {
    AccelerationLimits {
        forward_acceleration: bounded(fa),
        forward_deceleration: bounded(fd),
        yaw_acceleration_left: bounded(yl),
        yaw_acceleration_right: bounded(yr),
        ..Default::default()
    }
}

/// A generous setting: the envelope binds every value but y.
fn setting() -> SmootherLimits {
    SmootherLimits::from_setting(&[100.0, 0.4, 500.0], &[-100.0, -0.3, -500.0]).unwrap()
}

#[test]
fn forward_reversing_and_rest_pick_the_limits_of_their_direction() {
    let p = EnvelopeParams::default();
    let l = limits(9.0, 1.5, 120.0, 110.0);
    let (fwd, notes) = smoother_limits(&l, 0.5, &setting(), &p);
    assert!(notes.is_empty());
    assert_eq!(fwd.max_accel, [9.0, 0.4, 110.0]);
    assert_eq!(fwd.max_decel, [-1.5, -0.3, -110.0]);
    let (rev, _) = smoother_limits(&l, -0.5, &setting(), &p);
    assert_eq!(rev.max_accel, [1.5, 0.4, 110.0]);
    assert_eq!(rev.max_decel, [-9.0, -0.3, -110.0]);
    let (rest, _) = smoother_limits(&l, 0.0, &setting(), &p);
    assert_eq!(rest.max_accel, [1.5, 0.4, 110.0]);
    assert_eq!(rest.max_decel, [-1.5, -0.3, -110.0]);
}

#[test]
fn the_setting_caps_and_unbounded_keeps_it() {
    let p = EnvelopeParams::default();
    let s = SmootherLimits::from_setting(&[2.5, 0.0, 3.2], &[-2.5, 0.0, -3.2]).unwrap();
    let mut l = limits(9.0, 1.5, 120.0, 110.0);
    l.forward_acceleration.status = AccelerationLimit::UNBOUNDED;
    let (out, _) = smoother_limits(&l, 0.5, &s, &p);
    assert_eq!(out.max_accel, [2.5, 0.0, 3.2]);
    assert_eq!(out.max_decel, [-1.5, 0.0, -3.2]);
}

#[test]
fn limits_at_or_below_the_floor_are_sent_as_the_floor() {
    let p = EnvelopeParams::default();
    let mut l = limits(9.0, -0.5, 120.0, 110.0);
    l.yaw_acceleration_left.status = AccelerationLimit::INFEASIBLE;
    let (out, notes) = smoother_limits(&l, 0.5, &setting(), &p);
    assert_eq!(out.max_decel[0], -p.linear_floor);
    assert_eq!(out.max_accel[2], p.angular_floor);
    assert_eq!(out.max_decel[2], -p.angular_floor);
    assert!(
        notes
            .iter()
            .any(|n| n.contains("forward deceleration -0.5000")),
        "{notes:?}"
    );
    assert!(
        notes
            .iter()
            .any(|n| n.contains("yaw acceleration left infeasible")),
        "{notes:?}"
    );
}

#[test]
fn settings_a_smoother_cannot_hold_are_refused() {
    assert!(SmootherLimits::from_setting(&[1.0, 0.0], &[-1.0, 0.0, -1.0]).is_err());
    assert!(SmootherLimits::from_setting(&[1.0, 0.0, 1.0], &[1.0, 0.0, -1.0]).is_err());
    assert!(SmootherLimits::from_setting(&[f64::NAN, 0.0, 1.0], &[-1.0, 0.0, -1.0]).is_err());
}

#[test]
fn the_dead_band_sends_tightening_at_once_and_loosening_after_the_interval() {
    let (band, interval) = (0.05, Duration::from_secs(1));
    let t0 = Instant::now();
    let at = |s: f64| t0 + Duration::from_secs_f64(s);
    let mk = |d: f64| SmootherLimits {
        max_accel: [2.0, 0.0, 3.0],
        max_decel: [-d, 0.0, -3.0],
    };
    let mut db = DeadBand::default();
    assert!(db.due(&mk(1.0), t0, band, interval));
    db.sent(mk(1.0), t0);
    // Within the band either way: nothing.
    assert!(!db.due(&mk(0.96), at(5.0), band, interval));
    assert!(!db.due(&mk(1.04), at(5.0), band, interval));
    // Tightening beyond the band: at once.
    assert!(db.due(&mk(0.94), at(0.1), band, interval));
    // Loosening beyond the band: only after the interval.
    assert!(!db.due(&mk(1.2), at(0.5), band, interval));
    assert!(db.due(&mk(1.2), at(1.0), band, interval));
}
