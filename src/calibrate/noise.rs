//! The process noise: what the model still misses after the fit, stated on the wheels and the
//! base so that the predicted covariance covers it.
//!
//! Two terms on every wheel joint (docs/propagation.md): a white acceleration noise of density σ
//! [(rad/s²)/√Hz] at all times (`uncertainty.acceleration_noise`), and, while the wheel's
//! controller is saturated, an acceleration offset of standard deviation σ_b [rad/s²], the same
//! through a prediction (`uncertainty.saturation_bias`): at the grip's limit — a skid, a wheel
//! unloaded as the robot pitches — the model knows least what the floor takes, and that error
//! lasts as long as the skid. Through the rolling constraints they spread the base's position
//! along the travel and its yaw, growing with the horizon. Beside σ_b, while the drive is
//! saturated, a rate offset of standard deviation σ_k [m/s] on the base's two horizontal
//! positions (`uncertainty.saturation_slip`): the skid's slide, which reaches across the path
//! where a wheel's offset cannot. And a slip noise σ_s [rad/√s] on the base's yaw
//! (`uncertainty.slip_noise`): the heading's random walk outside the constraints, which the
//! wheel controllers do not take back as they take back the wheels' noise.
//!
//! σ is the smallest value whose predicted covariance (the node's: propagated, error estimate
//! and floors, plus the reference's own) holds the target fraction of the predictions through
//! no saturation inside its 95 % region at every fit horizon (doubling, then bisection of log
//! σ). Not on a scene with tyres: their grip rejects such noise ([`TYRES_REJECT_NOISE`]). σ_b
//! and σ_k act on the predictions through a saturation, and together: for a σ_k, σ_b is the
//! smallest value that covers those predictions as σ covers the others (stepping through
//! [`BIAS_TRIED`], or down from the σ_b of a smaller σ_k, then bisection of log σ_b), and σ_k
//! is the value whose pair has the lowest log score (0, then up from [`SLIDE_START`] by factors
//! of 2 while the score falls; a pair that covers before one that does not). A coverage count
//! alone would take σ_b up until the skids' errors across the path fall inside a region grown
//! along it and in yaw; the likelihood weighs the region's shape. σ_s, beside them, is the most
//! likely value (the lowest log score): the wheels' terms may already cover the calibration
//! drive's errors, which the fit itself took down, while a fresh drive's heading drifts more.

use super::{CalibrationError, CalibrationSettings, Problem};
use crate::replay::{EvaluationSettings, evaluate, stats::Coverage};
use nalgebra::Matrix3;
use serde::Serialize;
use serde_yaml::Value;

/// The fitted process noise.
#[derive(Clone, Debug, Serialize)]
pub struct ProcessNoise {
    /// The joints it is on (the wheels').
    pub joints: Vec<String>,
    /// σ [(rad/s²)/√Hz].
    pub acceleration_noise: f64,
    /// σ_b [rad/s²], while a wheel's controller is saturated.
    pub saturation_bias: f64,
    /// The base's horizontal coordinates the skid's slide is on.
    pub saturation_slip_coordinates: Vec<String>,
    /// σ_k [m/s], while the drive is saturated: the lowest log score with its σ_b.
    pub saturation_slip: f64,
    /// The base's yaw coordinate the slip noise is on, if the base has one.
    pub slip_coordinate: Option<String>,
    /// σ_s [rad/√s]: the yaw's random walk, the most likely value beside σ and σ_b.
    pub slip_noise: f64,
    /// The fraction of the replayed errors inside the 95 % region with them, over every fit
    /// horizon.
    pub coverage_p95: f64,
    /// The same among the predictions through no saturation, at the fit horizon where it is
    /// least.
    pub unsaturated_coverage_p95: f64,
    /// The same among the predictions through a saturation, at the fit horizon where it is
    /// least.
    pub saturated_coverage_p95: f64,
    /// How many predictions pass through a saturation.
    pub saturated_predictions: usize,
    /// The predictions' mean negative log-likelihood with them (½ (NEES + ln det P), P the
    /// pose covariance in m and rad; lower is better).
    pub log_score: f64,
    /// Replays it took.
    pub replays: usize,
    /// Why σ was not fitted, where it was not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_fitted: Option<&'static str>,
}

/// A tyre's grip ties its wheel to the floor at the tyre's slip rate (~10⁴ /s) and the wheel's
/// controller holds its speed: acceleration noise on a wheel (or on the base) is rejected
/// within milliseconds and spreads no pose (σ = 30 (rad/s²)/√Hz on the soft-floor robot's
/// wheels moves validation_smooth's mean NEES at 1 s from 4.3 to 4.1).
const TYRES_REJECT_NOISE: &str =
    "the tyres' grip and the wheel controllers reject acceleration noise on the wheels";

/// Bisection steps of log σ after the bracket: the bracket's factor 2 to 2^(1/64).
const BISECTIONS: usize = 6;
/// The largest and smallest σ tried [(rad/s²)/√Hz].
const LARGEST: f64 = 1e4;
const SMALLEST: f64 = 1e-4;
/// σ_b tried [rad/s²], in order, until the predictions through a saturation are covered. A
/// wheel's offset reaches the base only through the rolling constraints, which give most of it
/// back to the wheel (its inertia is a few thousandths of the robot's on the wheel's axis), so
/// the values that matter are large, less so beside a skid's slide.
const BIAS_TRIED: [f64; 8] = [1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0];
/// Bisection steps of log σ_b between the last value of [`BIAS_TRIED`] that does not cover
/// and the first that does: their factor ≈ 3 to ≈ 1.15.
const BIAS_BISECTIONS: usize = 3;
/// The least and the largest skid slide tried [m/s] (0.01: 1 mm over a 0.1 s skid, below the
/// odometry's position noise).
const SLIDE_START: f64 = 0.01;
const SLIDE_LARGEST: f64 = 1.0;
/// Where σ's bracket starts [(rad/s²)/√Hz].
const SIGMA_START: f64 = 0.1;
/// The least and the largest yaw slip noise tried [rad/√s] (1e-4: 0.14 mrad in 2 s, far
/// below any odometry's yaw noise), and the factor the golden section resolves it to.
const SLIP_START: f64 = 1e-4;
const SLIP_LARGEST: f64 = 1.0;
const SLIP_RESOLUTION: f64 = 1.1;

/// One trial's coverages (as [`ProcessNoise`] states them) and log score.
#[derive(Clone, Copy)]
struct Score {
    coverage_p95: f64,
    unsaturated_coverage_p95: f64,
    saturated_coverage_p95: f64,
    saturated: usize,
    log_score: f64,
}

/// Fits the process noise for the scene `yaml` (the fitted one) and writes it in; σ_k searched
/// for, or kept at `kept_slide` where given (a refit after the values moved a little: the search
/// costs three times the rest, and its factor-2 steps do not move with them).
pub(super) fn fit(
    problem: &Problem,
    yaml: &mut Value,
    settings: &CalibrationSettings,
    kept_slide: Option<f64>,
) -> Result<ProcessNoise, CalibrationError> {
    let replay = EvaluationSettings {
        propagate_covariance: true,
        ..settings.replay.clone()
    };
    // The fit owns its four terms: every trial and the result set them all, 0 included, so
    // that what is scored is what is written.
    let write = |yaml: &mut Value, [sigma, bias, slide, slip]: [f64; 4]| {
        (problem.places).set_wheel_noise(yaml, "acceleration_noise", sigma);
        (problem.places).set_wheel_noise(yaml, "saturation_bias", bias);
        (problem.places).set_skid_slide(yaml, slide);
        (problem.places).set_yaw_slip(yaml, slip);
    };
    let mut replays = 0;
    // [σ, σ_b, σ_k, σ_s].
    let mut score = |terms: [f64; 4]| -> Result<Score, CalibrationError> {
        let mut trial = yaml.clone();
        write(&mut trial, terms);
        let scene = problem.source.build(&trial)?;
        let (mut nees, mut log_score) = (Vec::new(), 0.0);
        let horizons = &replay.horizons_s;
        let (mut saturated, mut unsaturated) =
            (vec![vec![]; horizons.len()], vec![vec![]; horizons.len()]);
        for recording in problem.recordings {
            let ev = evaluate(&scene, recording, &replay)?;
            for r in &ev.records {
                let p =
                    Matrix3::from(r.predicted_covariance) + Matrix3::from(r.reference_covariance);
                log_score += 0.5 * (r.nees + p.determinant().max(f64::MIN_POSITIVE).ln());
                nees.push(r.nees);
                let k = horizons.iter().position(|&h| h == r.horizon_s).unwrap_or(0);
                if r.saturated_s > 0.0 {
                    saturated[k].push(r.nees);
                } else {
                    unsaturated[k].push(r.nees);
                }
            }
        }
        replays += 1;
        // A subset's coverage at the horizon where it is least.
        let least = |by_horizon: &[Vec<f64>]| {
            (by_horizon.iter())
                .filter(|n| !n.is_empty())
                .map(|n| Coverage::of(n).p95)
                .fold(1.0, f64::min)
        };
        Ok(Score {
            coverage_p95: if nees.is_empty() {
                0.0
            } else {
                Coverage::of(&nees).p95
            },
            unsaturated_coverage_p95: least(&unsaturated),
            saturated_coverage_p95: least(&saturated),
            saturated: saturated.iter().map(Vec::len).sum(),
            log_score: log_score / nees.len().max(1) as f64,
        })
    };
    let target = settings.target_coverage_p95;
    let joints = problem.places.wheel_joints().to_vec();
    let s0 = score([0.0; 4])?;
    let tyres = problem.places.tyres_carry_wheels();
    let (mut sigma, mut bias, mut slide, mut s) = (0.0, 0.0, 0.0, s0);
    let covered = s0.unsaturated_coverage_p95 >= target && s0.saturated_coverage_p95 >= target;
    if !(covered || joints.is_empty() || tyres) {
        // σ on the predictions only it acts on; then σ_b and σ_k, beside it, on those through
        // a saturation.
        (sigma, s) = smallest_sigma(|sigma| score([sigma, 0.0, 0.0, 0.0]), target)?;
        let mut pair = |slide: f64, bound: Bound| {
            smallest_bias(|b| score([sigma, b, slide, 0.0]), bound, target)
        };
        let slides = !problem.places.base_horizontal().is_empty() && s.saturated > 0;
        match kept_slide {
            Some(k) if slides && k > 0.0 => (slide, (bias, s)) = (k, pair(k, Bound::None)?),
            _ => (bias, s) = pair(0.0, Bound::Zero(s))?,
        }
        if slides && kept_slide.is_none() {
            (slide, bias, s) = most_likely_slide(&mut pair, (bias, s), target)?;
        }
    }
    let mut slip = 0.0;
    if problem.places.base_yaw().is_some() {
        (slip, s) = most_likely_slip(|slip| score([sigma, bias, slide, slip]), s)?;
    }
    write(yaml, [sigma, bias, slide, slip]);
    Ok(ProcessNoise {
        joints,
        acceleration_noise: sigma,
        saturation_bias: bias,
        saturation_slip_coordinates: problem.places.base_horizontal().to_vec(),
        saturation_slip: slide,
        slip_coordinate: problem.places.base_yaw().map(str::to_string),
        slip_noise: slip,
        coverage_p95: s.coverage_p95,
        unsaturated_coverage_p95: s.unsaturated_coverage_p95,
        saturated_coverage_p95: s.saturated_coverage_p95,
        saturated_predictions: s.saturated,
        log_score: s.log_score,
        replays,
        not_fitted: (tyres && s.coverage_p95 < target).then_some(TYRES_REJECT_NOISE),
    })
}

/// What is known of σ_b before its search: nothing, the score without it (at this σ_k), or a
/// σ_b that covers — covering at a smaller σ_k, it covers here: more variance lowers every
/// NEES.
#[derive(Clone, Copy)]
enum Bound {
    None,
    Zero(Score),
    Covers(f64),
}

/// The smallest σ_b (to a factor ≈ 1.15) whose `score` covers `target` of the predictions
/// through a saturation: 0 where that already holds, else the first of [`BIAS_TRIED`] that
/// covers them — or, below a `bound` that covers, down from it by factors of 3 — bisected down
/// from there.
fn smallest_bias(
    mut score: impl FnMut(f64) -> Result<Score, CalibrationError>,
    bound: Bound,
    target: f64,
) -> Result<(f64, Score), CalibrationError> {
    let covered = |s: &Score| s.saturated_coverage_p95 >= target;
    let (mut lo, mut bias, mut s);
    if let Bound::Covers(b) = bound {
        // σ_b's own score is taken only where no smaller value covers.
        let (mut hi, mut at_hi) = (b, None);
        lo = 0.0;
        while hi > 0.0 {
            let down = hi / 3.0;
            if down < BIAS_TRIED[0] {
                let at_zero = score(0.0)?;
                if covered(&at_zero) {
                    return Ok((0.0, at_zero));
                }
                lo = down;
                break;
            }
            let at = score(down)?;
            if !covered(&at) {
                lo = down;
                break;
            }
            (hi, at_hi) = (down, Some(at));
        }
        bias = hi;
        s = match at_hi {
            Some(at) => at,
            None => score(hi)?,
        };
    } else {
        s = match bound {
            Bound::Zero(s) => s,
            _ => score(0.0)?,
        };
        if covered(&s) {
            return Ok((0.0, s));
        }
        (lo, bias) = (0.0, 0.0);
        for b in BIAS_TRIED {
            (bias, s) = (b, score(b)?);
            if covered(&s) {
                break;
            }
            lo = b;
        }
    }
    if covered(&s) && lo > 0.0 {
        for _ in 0..BIAS_BISECTIONS {
            let mid = (lo * bias).sqrt();
            let at = score(mid)?;
            if covered(&at) {
                (bias, s) = (mid, at);
            } else {
                lo = mid;
            }
        }
    }
    Ok((bias, s))
}

/// The σ_k whose pair (σ_b from `pair`, bounded by the best σ_k's σ_b where that covers
/// `target`) has the lowest log score, `at_zero` being σ_b and its score without a slide: up
/// from [`SLIDE_START`] by factors of 2 while the score falls. A pair that covers is preferred
/// to one that does not, and while none does the search goes on up: where no σ_b covers the
/// skids' errors (they lie across the path, out of the wheels' reach), the slide is what can.
/// (σ_k, σ_b, score).
fn most_likely_slide(
    mut pair: impl FnMut(f64, Bound) -> Result<(f64, Score), CalibrationError>,
    at_zero: (f64, Score),
    target: f64,
) -> Result<(f64, f64, Score), CalibrationError> {
    let covers = |s: &Score| s.saturated_coverage_p95 >= target;
    let mut best = (0.0, at_zero.0, at_zero.1);
    let mut k = SLIDE_START;
    while k <= SLIDE_LARGEST {
        // A σ_b that covers bounds the next one; where even the largest tried did not, the
        // search starts afresh.
        let bound = if covers(&best.2) {
            Bound::Covers(best.1)
        } else {
            Bound::None
        };
        let (b, s) = pair(k, bound)?;
        let better = match (covers(&s), covers(&best.2)) {
            (true, false) => true,
            (false, true) => false,
            _ => s.log_score < best.2.log_score,
        };
        if better {
            best = (k, b, s);
        } else if covers(&best.2) {
            break;
        }
        k *= 2.0;
    }
    Ok(best)
}

/// The σ_s (to [`SLIP_RESOLUTION`]) with the lowest log score, `at_zero` being the score
/// without it: up from [`SLIP_START`] by factors of 2 while the score falls, then a golden
/// section of log σ_s around the best. 0 where the least tried already scores worse.
fn most_likely_slip(
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
fn smallest_sigma(
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
