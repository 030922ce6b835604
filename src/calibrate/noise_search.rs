//! The searches of the process noise's terms (noise.rs), each on a score function of its
//! term's value.

use super::{CalibrationError, Score};

/// Bisection steps of log σ after the bracket: the bracket's factor 2 to 2^(1/64).
const BISECTIONS: usize = 6;
/// The largest and smallest σ_τ tried [(N·m)/√Hz].
const LARGEST: f64 = 1e4;
const SMALLEST: f64 = 1e-4;
/// The least and the largest skid slide tried [m/s] (0.01: 1 mm over a 0.1 s skid, below the
/// odometry's position noise).
const SLIDE_START: f64 = 0.01;
const SLIDE_LARGEST: f64 = 1.0;
/// The least and the largest skid turn tried [rad/s] (0.01: 1 mrad over a 0.1 s skid, below
/// the odometry's yaw noise).
const TURN_START: f64 = 0.01;
const TURN_LARGEST: f64 = 2.0;
/// Where σ_τ's bracket starts [(N·m)/√Hz].
const SIGMA_START: f64 = 0.1;
/// The least and the largest yaw slip noise tried [rad/√s] (1e-4: 0.14 mrad in 2 s, far
/// below any odometry's yaw noise), and the factor the golden section resolves it to.
const SLIP_START: f64 = 1e-4;
const SLIP_LARGEST: f64 = 1.0;
const SLIP_RESOLUTION: f64 = 1.1;

/// The skid's slide σ_k and turn σ_t with the lowest log score among the pairs that cover
/// `target` of the predictions through a saturation (among all, where none does): every pair
/// of 0 and the values up from [`SLIDE_START`] and [`TURN_START`] by factors of 2, then the
/// pairs a factor √2 either side of the best. Cheap: the scores are sums (noise_basis.rs).
/// A term the base cannot take (`no_slide`, `no_turn`) stays 0. (σ_k, σ_t, score).
pub(super) fn most_likely_skid(
    mut score: impl FnMut(f64, f64) -> Result<Score, CalibrationError>,
    no_slide: bool,
    no_turn: bool,
    target: f64,
) -> Result<(f64, f64, Score), CalibrationError> {
    let ladder = |start: f64, largest: f64, none: bool| -> Vec<f64> {
        let mut v = vec![0.0];
        let mut x = start;
        while x <= largest && !none {
            v.push(x);
            x *= 2.0;
        }
        v
    };
    let better = |a: &Score, b: &Score| match (
        a.saturated_coverage_p95 >= target,
        b.saturated_coverage_p95 >= target,
    ) {
        (true, false) => true,
        (false, true) => false,
        _ => a.log_score < b.log_score,
    };
    let mut best = (0.0, 0.0, score(0.0, 0.0)?);
    let mut consider = |k: f64, t: f64, best: &mut (f64, f64, Score)| {
        if (k, t) != (best.0, best.1) {
            let s = score(k, t)?;
            if better(&s, &best.2) {
                *best = (k, t, s);
            }
        }
        Ok::<(), CalibrationError>(())
    };
    for &k in &ladder(SLIDE_START, SLIDE_LARGEST, no_slide) {
        for &t in &ladder(TURN_START, TURN_LARGEST, no_turn) {
            consider(k, t, &mut best)?;
        }
    }
    let (k0, t0) = (best.0, best.1);
    let around = |x: f64| {
        if x > 0.0 {
            vec![x / 2f64.sqrt(), x, x * 2f64.sqrt()]
        } else {
            vec![0.0]
        }
    };
    for &k in &around(k0) {
        for &t in &around(t0) {
            consider(k, t, &mut best)?;
        }
    }
    Ok(best)
}

/// The σ_s (to [`SLIP_RESOLUTION`]) with the lowest log score, `at_zero` being the score
/// without it: up from [`SLIP_START`] by factors of 2 while the score falls, then a golden
/// section of log σ_s around the best. 0 where the least tried already scores worse.
pub(super) fn most_likely_slip(
    mut score: impl FnMut(f64) -> Result<Score, CalibrationError>,
    at_zero: Score,
) -> Result<(f64, Score), CalibrationError> {
    let mut best = (0.0, at_zero);
    let mut x = SLIP_START;
    while x <= SLIP_LARGEST {
        let s = score(x)?;
        if s.log_score >= best.1.log_score {
            break;
        }
        best = (x, s);
        x *= 2.0;
    }
    if best.0 == 0.0 {
        return Ok(best);
    }
    // The minimum lies within a factor 2 of the best tried: golden section of log σ_s.
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut lo, mut hi) = ((best.0 / 2.0).ln(), (best.0 * 2.0).ln());
    let mut a = (hi - g * (hi - lo), score((hi - g * (hi - lo)).exp())?);
    let mut b = (lo + g * (hi - lo), score((lo + g * (hi - lo)).exp())?);
    while hi - lo > SLIP_RESOLUTION.ln() {
        if a.1.log_score < b.1.log_score {
            (hi, b) = (b.0, a);
            let x = hi - g * (hi - lo);
            a = (x, score(x.exp())?);
        } else {
            (lo, a) = (a.0, b);
            let x = lo + g * (hi - lo);
            b = (x, score(x.exp())?);
        }
    }
    for (x, s) in [a, b] {
        if s.log_score < best.1.log_score {
            best = (x.exp(), s);
        }
    }
    Ok(best)
}

/// The smallest σ (to 2^(1/64)) whose `score` covers `target` of the predictions through no
/// saturation, bracketed by factors of 2 from [`SIGMA_START`]; σ = 0 where that already covers
/// it.
pub(super) fn smallest_sigma(
    mut score: impl FnMut(f64) -> Result<Score, CalibrationError>,
    target: f64,
) -> Result<(f64, Score), CalibrationError> {
    let (mut lo, mut hi) = (0.0, SIGMA_START);
    let mut s_hi = score(hi)?;
    if s_hi.unsaturated_coverage_p95 >= target {
        lo = hi / 2.0;
        loop {
            if lo <= SMALLEST {
                let s = score(0.0)?;
                if s.unsaturated_coverage_p95 >= target {
                    return Ok((0.0, s));
                }
                break;
            }
            let s = score(lo)?;
            if s.unsaturated_coverage_p95 < target {
                break;
            }
            (hi, s_hi) = (lo, s);
            lo /= 2.0;
        }
    } else {
        while s_hi.unsaturated_coverage_p95 < target && hi < LARGEST {
            lo = hi;
            hi *= 2.0;
            s_hi = score(hi)?;
        }
    }
    for _ in 0..BISECTIONS {
        let mid = if lo > 0.0 { (lo * hi).sqrt() } else { hi / 2.0 };
        let s = score(mid)?;
        if s.unsaturated_coverage_p95 >= target {
            (hi, s_hi) = (mid, s);
        } else {
            lo = mid;
        }
    }
    Ok((hi, s_hi))
}

#[cfg(test)]
#[path = "noise_tests.rs"]
mod tests;
