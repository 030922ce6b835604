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

/// No σ_b covers the skids without a slide (their errors lie across the path), and a small
/// slide's pair scores worse than none; from 0.04 m/s on the pairs cover, most likely at
/// 0.08. The search goes on past the pairs that do not cover and lands on 0.08, each covering
/// pair's search bounded by the last covering σ_b.
#[test]
fn a_slide_that_covers_is_found_past_ones_that_do_not() {
    let mut bounds = Vec::new();
    let pair = |k: f64, bound: Bound| {
        bounds.push((k, matches!(bound, Bound::Covers(_))));
        let covered = k >= 0.04 - 1e-12;
        let log_score = if covered {
            -13.0 + 100.0 * (k.ln() - 0.08f64.ln()).powi(2)
        } else {
            -9.0
        };
        Ok((
            if covered { 5.0 } else { 3000.0 },
            score(covered, log_score),
        ))
    };
    let (slide, bias, s) = most_likely_slide(pair, (3000.0, score(false, -10.0)), 0.95).unwrap();
    assert_eq!((slide, bias), (0.08, 5.0));
    assert_eq!(s.log_score, -13.0);
    assert_eq!(
        bounds,
        [
            (0.01, false),
            (0.02, false),
            (0.04, false),
            (0.08, true),
            (0.16, true)
        ]
    );
}

/// Where no slide lets any σ_b cover, the most likely pair tried stays: here none.
#[test]
fn no_covering_slide_keeps_the_most_likely() {
    let pair = |k: f64, _: Bound| Ok((3000.0, score(false, -10.0 + k)));
    let (slide, _, s) = most_likely_slide(pair, (3000.0, score(false, -10.0)), 0.95).unwrap();
    assert_eq!((slide, s.log_score), (0.0, -10.0));
}

/// On a tyre scene the skid's slide and turn are searched together: the pairs cover from
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
