//! The skid searches (noise_search.rs) on scores with a known best.

use super::*;

fn score(covered: bool, log_score: f64) -> Score {
    Score {
        coverage_p95: 0.95,
        unsaturated_coverage_p95: 0.95,
        saturated_coverage_p95: if covered { 0.96 } else { 0.9 },
        saturated: 10,
        log_score,
    }
}

/// The skid's slide and turn are searched together: the pairs cover from
/// (0.04 m/s, 0.08 rad/s) on, and the log score is least at (0.16, 0.32), on the ladders; a
/// term the base cannot take stays 0.
#[test]
fn the_most_likely_skid_pair_is_found_on_the_ladders() {
    let skid = |k: f64, t: f64| {
        let covered = k >= 0.04 - 1e-12 && t >= 0.08 - 1e-12;
        let log = |x: f64, at: f64| if x > 0.0 { (x / at).ln().powi(2) } else { 50.0 };
        Ok(score(covered, -13.0 + log(k, 0.16) + log(t, 0.32)))
    };
    let (k, t, s) = most_likely_skid(skid, false, false, 0.95).unwrap();
    assert_eq!((k, t, s.log_score), (0.16, 0.32, -13.0));
    let (k, t, s) = most_likely_skid(skid, false, true, 0.95).unwrap();
    assert_eq!((k, t), (0.16, 0.0));
    assert!(s.saturated_coverage_p95 < 0.95);
}
