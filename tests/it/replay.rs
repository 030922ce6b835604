//! The replay's plain parts (`src/replay/`): the χ²(3) bounds against the closed-form CDF, the
//! order statistics against hand counts, "the last sample at or before t" at exact nanosecond
//! instants, and a recording's refusals naming the series and the time.

use constraint_dynamics::replay::stats::{CHI2_3_P50, CHI2_3_P95, Coverage, Spread, nees};
use constraint_dynamics::replay::{JointStates, Recording, Series};

/// P(χ²(3) ≤ x) = erf(√(x/2)) − √(2x/π) e^(−x/2), erf by its Taylor series.
fn chi2_3_cdf(x: f64) -> f64 {
    let z = (x / 2.0).sqrt();
    let (mut term, mut sum, mut n) = (z, z, 0.0);
    while term.abs() > 1e-18 * sum.abs() {
        n += 1.0;
        term *= -z * z / n;
        sum += term / (2.0 * n + 1.0);
    }
    2.0 / std::f64::consts::PI.sqrt() * sum
        - (2.0 * x / std::f64::consts::PI).sqrt() * (-x / 2.0).exp()
}

#[test]
fn chi2_bounds_are_the_quantiles_of_chi2_3() {
    assert!((chi2_3_cdf(CHI2_3_P50) - 0.5).abs() < 1e-12);
    assert!((chi2_3_cdf(CHI2_3_P95) - 0.95).abs() < 1e-12);
    // A unit covariance: NEES is |e|².
    let eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert!((nees([1.0, 2.0, 2.0], eye).unwrap() - 9.0).abs() < 1e-12);
    // diag(4, 1, 1): e = (2, 0, 0) is one σ.
    let d = [[4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert!((nees([2.0, 0.0, 0.0], d).unwrap() - 1.0).abs() < 1e-12);
    assert!(nees([1.0, 0.0, 0.0], [[0.0; 3]; 3]).is_none());
    // NEES 1, 2, 3, 8, 9: two inside the 50 % region (≤ 2.366), three inside the 95 % one.
    let c = Coverage::of(&[1.0, 2.0, 3.0, 8.0, 9.0]);
    assert_eq!((c.p50, c.p95), (0.4, 0.6));
}

#[test]
fn spread_interpolates_between_order_statistics() {
    // 1..=21: median 11, p95 at rank 19 → 20, max 21.
    let v: Vec<f64> = (1..=21).rev().map(f64::from).collect();
    let s = Spread::of(&v);
    assert_eq!((s.median, s.p95, s.max), (11.0, 20.0, 21.0));
    // [0, 10]: median 5, p95 9.5.
    let s = Spread::of(&[10.0, 0.0]);
    assert_eq!((s.median, s.p95, s.max), (5.0, 9.5, 10.0));
}

#[test]
fn lookups_are_exact_at_nanosecond_instants() {
    let mut s = Series::new("/odom");
    s.samples = vec![(0, 'a'), (20_000_000, 'b'), (40_000_000, 'c')];
    assert_eq!(s.at_or_before(20_000_000).unwrap().1, 'b');
    assert_eq!(s.at_or_before(19_999_999).unwrap().1, 'a');
    assert!(s.at_or_before(-1).is_none());
    let between: Vec<char> = s.between(0, 40_000_000).iter().map(|x| x.1).collect();
    assert_eq!(between, ['b', 'c']);
}

#[test]
fn a_recording_names_the_series_and_time_it_refuses() {
    let mut rec = Recording {
        odometry: Series::new("/odom"),
        reference: Series::new("/odom"),
        joint_states: Series::new("/joint_states"),
        commands: Series::new("/cmd_vel"),
    };
    let e = rec.check(500_000_000).unwrap_err().to_string();
    assert_eq!(e, "/odom: no messages");
    let js = |names: usize, pos: Vec<f64>| JointStates {
        name: (0..names).map(|k| format!("j{k}")).collect(),
        position: pos,
        ..Default::default()
    };
    let t0 = 1_000_000_000;
    rec.joint_states.samples = vec![
        (t0, js(2, vec![0.0, 0.0])),
        (t0 + 10_000_000, js(2, vec![0.0])),
    ];
    rec.odometry.samples = vec![];
    let e = rec
        .joint_states
        .check_times(t0, Some(1))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "/joint_states: no message for 0.010 s after 0.000 s (stamp 1.000000000); at most 0.000000001 s is allowed"
    );
    rec.commands.samples = vec![(t0, [0.0, f64::NAN])];
    rec.commands.samples.push((t0 - 5_000_000, [0.0, 0.0]));
    let e = rec
        .commands
        .check_times(t0 - 5_000_000, None)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "/cmd_vel: time goes back by 0.005 s at 0.000 s (stamp 0.995000000)"
    );
}
