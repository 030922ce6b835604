//! The prediction monitor allocates nothing after construction: recording predictions,
//! scoring odometry and joint states, command changes, the measured states' slip, the reports and the verdict (the predictor calls these per
//! message and per tick).

use constraint_dynamics::monitor::{
    MeasuredOdometry, MonitorSettings, PredictedSample, PredictionMonitor, Thresholds,
};

use crate::counting_alloc::allocations;

#[test]
fn recording_scoring_and_assessing_allocate_nothing() {
    let settings = MonitorSettings {
        horizons: vec![0.25, 0.5, 1.0],
        window: 50,
        pending: 13,
        max_lag: 0.1,
        slip_window: 20,
        thresholds: Thresholds {
            min_samples: 20,
            nees: 9.0,
            effort: 2.0,
            slip: 0.05,
            lag: 0.08,
            clear_ratio: 0.5,
        },
    };
    let mut m = PredictionMonitor::new(settings, 4);
    let p = [[1e-6, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 1e-6]];
    let effort = [0.0, 1.0, 2.0, 3.0];
    let run = |m: &mut PredictionMonitor, k0: usize| {
        for k in k0..k0 + 200 {
            let t = k as f64 * 0.1;
            for (i, h) in [0.25, 0.5, 1.0].into_iter().enumerate() {
                let s = PredictedSample {
                    start: t,
                    t: t + h,
                    pose: [0.3 * (t + h), 0.0, 0.0],
                    covariance: p,
                    effort: &effort,
                    position: &effort,
                    command: [0.3, 0.0],
                    start_velocity: [0.29, 0.0],
                };
                m.record(i, &s);
            }
            for j in 0..5 {
                let tm = t + 0.02 * j as f64;
                m.odometry(&MeasuredOdometry {
                    t: tm,
                    pose: [0.3 * tm + 1e-3, 0.0, 1e-3],
                    covariance: p,
                    twist: [0.3, 0.0, 0.0],
                });
                m.joint_states(tm, &[0.0, 1.0, 2.0, 3.5], &[0.5, 1.0, f64::NAN, 6.0]);
            }
            m.measured_state(0.02 + 1e-3 * (k % 7) as f64);
            let _ = m.slip_report();
            if k % 20 == 0 {
                m.command_changed(t + 0.05);
            }
            let _ = m.assess();
        }
    };
    run(&mut m, 0); // the first reports() fills its preallocated report list
    let n = allocations(|| run(&mut m, 200));
    assert_eq!(n, 0, "allocations while monitoring");
    // Sanity: the windows filled and joint 3's +3 N·m bias was seen.
    let r = m.reports()[0];
    assert_eq!(r.odometry_samples, 50);
    assert_eq!(r.effort_worst.map(|(j, _)| j), Some(3));
}
