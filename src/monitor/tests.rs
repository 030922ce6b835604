//! The monitor against independent numbers: errors drawn from the stated covariance (χ²₃:
//! mean 3, median 2.366), known biases, and which cause the verdict names.

use super::*;
use crate::test_rng::Rng;

const HORIZONS: [f64; 3] = [0.25, 0.5, 1.0];
const WINDOW: usize = 50;

pub(super) fn settings() -> MonitorSettings {
    MonitorSettings {
        horizons: HORIZONS.to_vec(),
        window: WINDOW,
        pending: 16,
        max_lag: 0.05,
        slip_window: 20,
        thresholds: Thresholds {
            min_samples: 20,
            nees: 9.0,
            effort: 2.0,
            slip: 0.05,
            lag: 0.08,
            clear_ratio: 0.5,
        },
    }
}

/// The true base on an arc: v = 0.5 m/s, ω = 0.2 rad/s from the origin.
fn truth(t: f64) -> PlanarPose {
    let (v, w) = (0.5, 0.2);
    [v / w * (w * t).sin(), v / w * (1.0 - (w * t).cos()), w * t]
}
const TWIST: [f64; 3] = [0.5, 0.0, 0.2];

/// Predicted covariance (correlated x-yaw, as a turning base's) and the odometry's.
const P: PlanarCovariance = [[4e-6, 0.0, 2e-6], [0.0, 9e-6, 0.0], [2e-6, 0.0, 1e-5]];
const R: PlanarCovariance = [[4e-6, 0.0, 0.0], [0.0, 4e-6, 0.0], [0.0, 0.0, 4e-6]];

/// Cholesky factor of P + R.
fn chol_s() -> [[f64; 3]; 3] {
    let mut s = P;
    for i in 0..3 {
        for j in 0..3 {
            s[i][j] += R[i][j];
        }
    }
    let mut l = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let sum: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            l[i][j] = match i == j {
                true => (s[i][i] - sum).sqrt(),
                false => (s[i][j] - sum) / l[j][j],
            };
        }
    }
    l
}

/// A drive of `seconds`: predictions at 10 Hz (t₀ = k/10 + 3 ms, so measurements lag), odometry
/// and joint states at 50 Hz. Each measurement is the truth at its time plus `pose_error(t)`;
/// each effort the predicted 2.4 N·m (joint 0) and 0 (joint 1) plus `effort_error(t)`; each
/// joint position the predicted 0.5 rad (joint 0) and π (joint 1, measured as −π + 1 mrad: a
/// revolute joint reported modulo 2π, 1 mrad off). Calls `each(monitor, t)` after every
/// assessment (one per prediction).
fn drive(
    m: &mut PredictionMonitor,
    seconds: f64,
    pose_error: &mut dyn FnMut(f64) -> [f64; 3],
    effort_error: &mut dyn FnMut(f64) -> [f64; 2],
    each: &mut dyn FnMut(&mut PredictionMonitor, (Verdict, bool)),
) {
    let predicted_effort = [2.4, 0.0];
    let predicted_position = [0.5, std::f64::consts::PI];
    let measured_position = [0.5, -std::f64::consts::PI + 1e-3];
    let (mut k, mut j) = (0usize, 0usize);
    loop {
        let t_pred = k as f64 * 0.1 + 0.003;
        let t_meas = j as f64 * 0.02;
        if t_pred.min(t_meas) > seconds {
            break;
        }
        if t_pred <= t_meas {
            for (i, h) in HORIZONS.iter().enumerate() {
                let sample = PredictedSample {
                    start: t_pred,
                    t: t_pred + h,
                    pose: truth(t_pred + h),
                    covariance: P,
                    effort: &predicted_effort,
                    position: &predicted_position,
                    command: [f64::NAN; 2],
                    start_velocity: [f64::NAN; 2],
                };
                m.record(i, &sample);
            }
            let v = m.assess();
            each(m, v);
            k += 1;
        } else {
            let e = pose_error(t_meas);
            let p = truth(t_meas);
            m.odometry(&MeasuredOdometry {
                t: t_meas,
                pose: [p[0] + e[0], p[1] + e[1], p[2] + e[2]],
                covariance: R,
                twist: TWIST,
            });
            let de = effort_error(t_meas);
            let effort = [2.4 + de[0], de[1]];
            m.joint_states(t_meas, &measured_position, &effort);
            j += 1;
        }
    }
}

#[test]
fn errors_drawn_from_the_stated_covariance_give_chi_square_nees_and_no_alarm() {
    let mut m = PredictionMonitor::new(settings(), 2);
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let l = chol_s();
    let mut pose_error = |_t: f64| {
        let z = [rng.normal(), rng.normal(), rng.normal()];
        [0, 1, 2].map(|i| (0..=i).map(|k| l[i][k] * z[k]).sum::<f64>())
    };
    let mut effort_rng = Rng(7);
    let mut effort_error = |_t: f64| [0.5 * effort_rng.normal(), 0.5 * effort_rng.normal()];
    // Every WINDOW-th assessment the 1 s window holds WINDOW fresh samples (5 measurements per
    // prediction, one due each 0.1 s): the means and medians of disjoint windows.
    let (mut means, mut medians, mut k) = (Vec::new(), Vec::new(), 0);
    let mut alarms = 0;
    let seconds = 2000.0;
    drive(
        &mut m,
        seconds,
        &mut pose_error,
        &mut effort_error,
        &mut |m, (v, _)| {
            alarms += v.is_some() as usize;
            k += 1;
            if k % WINDOW == 0 && k > WINDOW {
                for r in m.reports() {
                    means.push(r.nees_mean);
                    medians.push(r.nees_median);
                }
            }
        },
    );
    assert_eq!(alarms, 0, "a consistent drive raised alarms");
    let n = means.len() as f64;
    let mean = means.iter().sum::<f64>() / n;
    // Each window's mean has σ = √(6/50) = 0.35; the three horizons' windows overlap in time
    // but not in samples: ≈ 3 × 400 windows, σ(mean) ≈ 0.35/√1200 = 0.010. 5σ.
    assert!(
        (mean - 3.0).abs() < 0.05,
        "mean NEES {mean} over {n} windows"
    );
    medians.sort_by(f64::total_cmp);
    let median = medians[medians.len() / 2];
    // χ²₃'s median 2.366; a 50-sample median's spread ≈ 0.3, the median of 1200 of them: 0.05.
    assert!(
        (median - 2.366).abs() < 0.1,
        "median of window medians {median}"
    );
    let r = m.reports();
    assert!(r.iter().all(|r| r.unmatched == 0), "{r:?}");
}

#[test]
fn a_known_bias_gives_its_median_and_nees() {
    let mut m = PredictionMonitor::new(settings(), 2);
    let mut rng = Rng(11);
    // Poses off by a constant (3 mm, −4 mm, 2 mrad): |(dx, dy)| = 5 mm exactly.
    let mut pose_error = |_t: f64| [3e-3, -4e-3, 2e-3];
    let mut effort_error = |_t: f64| [1.5 + 0.3 * rng.normal(), 0.0];
    drive(
        &mut m,
        20.0,
        &mut pose_error,
        &mut effort_error,
        &mut |_, _| {},
    );
    let mut s = P;
    for i in 0..3 {
        for j in 0..3 {
            s[i][j] += R[i][j];
        }
    }
    let known = nees([3e-3, -4e-3, 2e-3], &s).unwrap();
    for r in m.reports() {
        assert_eq!(r.odometry_samples, WINDOW);
        // Carried back 17 ms along the measured twist: off the arc by v·lag·(|dyaw| + ω·lag/2)
        // = 0.0085 m × 3.7 mrad = 3.1e-5 m (the measured heading is 2 mrad off).
        assert!((r.position_median - 5e-3).abs() < 3.5e-5, "{r:?}");
        assert!((r.yaw_median - 2e-3).abs() < 1e-9, "{r:?}");
        // 3.1e-5 of 5e-3 m: ≤ 2 × 0.6 % of the NEES (a quadratic form).
        assert!(
            (r.nees_median - known).abs() < 0.015 * known,
            "{r:?} vs {known}"
        );
        let (joint, e) = r.effort_worst.unwrap();
        // 50 samples, σ 0.3: the median's σ ≈ 1.25 · 0.3/√50 = 0.05.
        assert_eq!(joint, 0);
        assert!((e - 1.5).abs() < 0.2, "{r:?}");
        // Joint 1 measured at −π + 1 mrad, predicted at π: 1 mrad off across the wrap.
        assert_eq!(r.joint_position_samples, WINDOW);
        let (joint, e) = r.joint_position_worst.unwrap();
        assert_eq!(joint, 1);
        assert!((e - 1e-3).abs() < 1e-12, "{r:?}");
        assert_eq!(r.command_changed, 0);
    }
}

#[test]
fn predictions_whose_command_changed_before_they_were_due_are_not_scored() {
    let mut m = PredictionMonitor::new(settings(), 2);
    // The command changes at 10.0 s, and at every second from 30 s on (each prediction's
    // 1 s horizon then spans a change); the poses are 5 cm off whenever a prediction spans a
    // change (what the held command did not foresee), exact otherwise.
    let changes = |t0: f64, t1: f64| {
        let spans = |c: f64| t0 < c && c <= t1;
        spans(10.0) || (30..40).any(|c| spans(c as f64))
    };
    let mut next_change = 10.0;
    let mut scored_off = 0;
    let (mut k, mut j) = (0usize, 0usize);
    loop {
        let t_pred = k as f64 * 0.1 + 0.003;
        let t_meas = j as f64 * 0.02;
        if t_pred.min(t_meas) > 40.0 {
            break;
        }
        if next_change <= t_pred.min(t_meas) {
            m.command_changed(next_change);
            next_change = if next_change < 30.0 {
                30.0
            } else {
                next_change + 1.0
            };
        }
        if t_pred <= t_meas {
            for (i, h) in HORIZONS.iter().enumerate() {
                // The pose the held command leads to: off the truth where a change comes.
                let off = if changes(t_pred, t_pred + h) {
                    0.05
                } else {
                    0.0
                };
                let p = truth(t_pred + h);
                let sample = PredictedSample {
                    start: t_pred,
                    t: t_pred + h,
                    pose: [p[0] + off, p[1], p[2]],
                    covariance: P,
                    effort: &[0.0, 0.0],
                    position: &[],
                    command: [f64::NAN; 2],
                    start_velocity: [f64::NAN; 2],
                };
                m.record(i, &sample);
            }
            if m.assess().0.is_some() {
                scored_off += 1;
            }
            k += 1;
        } else {
            m.odometry(&MeasuredOdometry {
                t: t_meas,
                pose: truth(t_meas),
                covariance: R,
                twist: TWIST,
            });
            m.joint_states(t_meas, &[f64::NAN; 2], &[0.0, 0.0]);
            j += 1;
        }
    }
    assert_eq!(scored_off, 0, "a prediction spanning a change was scored");
    // A change at c spans the predictions started in [c − h, c), at k/10 + 3 ms: 2, 5 and 10
    // of them at 0.25, 0.5 and 1 s (disjoint for changes 1 s apart); 11 changes, all due by
    // 40 s.
    for (r, per_change) in m.reports().iter().zip([2, 5, 10]) {
        assert_eq!(r.command_changed, 11 * per_change, "{r:?}");
        // The exact poses, carried back along the arc to first order: v·ω·lag²/2 ≤ 1.5e-5 m.
        assert!(r.position_median < 2e-5, "{r:?}");
        assert_eq!(r.joint_position_samples, 0, "{r:?}");
    }
}

/// The verdicts over a drive that turns bad at 30 s and good again at 60 s, with the onsets.
fn verdicts_of(
    bad_poses: bool,
    bad_efforts: bool,
) -> (Vec<(f64, Verdict)>, usize, PredictionMonitor) {
    let mut m = PredictionMonitor::new(settings(), 2);
    let mut rng = Rng(3);
    let l = chol_s();
    let bad = |t: f64| (30.0..60.0).contains(&t);
    let mut pose_error = |t: f64| {
        let z = [rng.normal(), rng.normal(), rng.normal()];
        let mut e = [0, 1, 2].map(|i| (0..=i).map(|k| l[i][k] * z[k]).sum::<f64>());
        if bad_poses && bad(t) {
            // A base that covers 10 % less than predicted (a slipping floor): at 1 s, 5 cm.
            e[0] -= 0.05;
        }
        e
    };
    let mut erng = Rng(5);
    let mut effort_error = |t: f64| {
        let off = if bad_efforts && bad(t) { 5.0 } else { 0.0 };
        [off + 0.5 * erng.normal(), 0.5 * erng.normal()]
    };
    let (mut out, mut changes, mut k) = (Vec::new(), 0, 0);
    drive(
        &mut m,
        90.0,
        &mut pose_error,
        &mut effort_error,
        &mut |_, (v, changed)| {
            changes += changed as usize;
            out.push((k as f64 * 0.1, v));
            k += 1;
        },
    );
    (out, changes, m)
}

#[test]
fn the_verdict_names_a_payload_when_only_the_efforts_are_off() {
    let (verdicts, changes, _) = verdicts_of(false, true);
    let name = |j: usize| ["shoulder", "elbow"][j].to_string();
    let called: Vec<&(f64, Verdict)> = verdicts.iter().filter(|v| v.1.is_some()).collect();
    let (first, v) = called[0];
    // Called once the windows' medians cross 2 N·m (half the window bad: ~25 samples), ≥ 30 s.
    assert!((30.0..36.0).contains(first), "first called at {first}");
    let text = v.unwrap().describe(&name);
    assert!(matches!(v, Some(Cause::Efforts { joint: 0, .. })), "{v:?}");
    assert!(
        text.contains("shoulder") && text.contains("payload"),
        "{text}"
    );
    let (last, _) = called.last().unwrap();
    assert!((60.0..66.0).contains(last), "last called at {last}");
    // One onset and one clearing: no flapping.
    assert_eq!(changes, 2);
}

#[test]
fn the_verdict_names_the_floor_or_wheels_when_the_poses_are_off() {
    let (verdicts, changes, _) = verdicts_of(true, false);
    let called: Vec<&(f64, Verdict)> = verdicts.iter().filter(|v| v.1.is_some()).collect();
    let (first, v) = called[0];
    assert!((30.0..36.0).contains(first), "first called at {first}");
    assert!(matches!(v, Some(Cause::Poses { .. })), "{v:?}");
    let text = v.unwrap().describe(&|j| j.to_string());
    assert!(text.contains("slippery floor"), "{text}");
    assert_eq!(changes, 2);
    let (_, both, _) = verdicts_of(true, true);
    assert!(both >= 2);
    let (v, _, _) = verdicts_of(true, true);
    assert!(
        v.iter().any(|(_, v)| matches!(v, Some(Cause::Both { .. }))),
        "both off: Both"
    );
}

/// The measured states' velocity residual alone calls the wheels slipping: residuals of
/// |N(0.02, 0.01)| m/s (a 50 Hz odometry's twist noise against the wheels' speeds), then from
/// 30 s 0.15 m/s on every other state (wheels spinning in the ramps of a drive on a slippery
/// floor), then the noise again from 60 s. The median of the last 20 (2 s at 10 Hz) passes
/// 0.05 m/s once more than half the window slips, and clears below half of it: one onset, one
/// clearing; nothing before the window fills.
#[test]
fn the_verdict_names_a_slippery_floor_when_the_wheels_slip() {
    let mut m = PredictionMonitor::new(settings(), 2);
    let mut rng = Rng(7);
    let (mut changes, mut called) = (0, Vec::new());
    for k in 0..900 {
        let t = k as f64 * 0.1;
        let slipping = (30.0..60.0).contains(&t) && k % 2 == 0;
        let residual = match slipping {
            true => 0.15,
            false => (0.02 + 0.01 * rng.normal()).abs(),
        };
        m.measured_state(residual);
        let (v, changed) = m.assess();
        changes += changed as usize;
        if k < 19 {
            assert!(v.is_none(), "called before the window filled, at {t} s");
        }
        if let Some(c) = v {
            called.push((t, c));
        }
    }
    let (first, v) = called[0];
    assert!((30.0..32.0).contains(&first), "first called at {first}");
    assert!(
        matches!(v, Cause::Slip { residual } if residual > 0.05),
        "{v:?}"
    );
    assert!(v.describe(&|j| j.to_string()).contains("slippery floor"));
    let (last, _) = called.last().unwrap();
    assert!((60.0..62.0).contains(last), "last called at {last}");
    assert_eq!(changes, 2, "one onset and one clearing");
    let r = m.slip_report();
    assert_eq!(r.samples, 20);
    assert!((0.01..0.035).contains(&r.residual_median), "{r:?}");
}

#[test]
fn nothing_is_called_before_min_samples() {
    let mut m = PredictionMonitor::new(settings(), 2);
    let mut called_at = None;
    let mut k = 0;
    drive(
        &mut m,
        10.0,
        &mut |_| [0.1, 0.0, 0.0],
        &mut |_| [10.0, 0.0],
        &mut |m, (v, _)| {
            k += 1;
            if v.is_some() && called_at.is_none() {
                called_at = Some(m.reports().iter().map(|r| r.odometry_samples).max());
            }
        },
    );
    // The 0.25 s horizon reaches 20 samples first.
    assert_eq!(called_at, Some(Some(20)));
}

#[test]
fn joint_states_that_each_give_some_joints_score_every_joint() {
    // As a robot with two drivers publishes: joint 0's position alone, then joint 1's position
    // and both efforts, 1 ms later, every 20 ms. Each joint is scored by the message that
    // gives it: 1 rad and 2 N·m off on joint 0, −1 mrad and 0.5 N·m on joint 1.
    let mut m = PredictionMonitor::new(settings(), 2);
    let (predicted_q, predicted_e) = ([0.0, 0.0], [1.0, 1.0]);
    let nan = f64::NAN;
    for k in 0..400 {
        let t = k as f64 * 0.02;
        if k % 5 == 0 {
            for (i, h) in HORIZONS.iter().enumerate() {
                let sample = PredictedSample {
                    start: t,
                    t: t + h,
                    pose: truth(t + h),
                    covariance: P,
                    effort: &predicted_e,
                    position: &predicted_q,
                    command: [f64::NAN; 2],
                    start_velocity: [f64::NAN; 2],
                };
                m.record(i, &sample);
            }
        }
        m.joint_states(t, &[1.0, nan], &[nan, nan]);
        m.joint_states(t + 0.001, &[nan, -1e-3], &[3.0, 1.5]);
    }
    for r in m.reports() {
        assert_eq!(r.joint_position_samples, WINDOW, "{r:?}");
        assert_eq!(r.effort_samples, WINDOW, "{r:?}");
        assert_eq!(r.joint_position_worst, Some((0, 1.0)), "{r:?}");
        assert_eq!(r.effort_worst, Some((0, 2.0)), "{r:?}");
    }
}
