//! The process noise: what the model still misses after the fit, stated on the wheels and the
//! base so that the predicted covariance covers it.
//!
//! Four terms (docs/propagation.md). On every wheel joint a white effort noise of density σ_τ
//! [(N·m)/√Hz] at all times (`uncertainty.effort_noise`): the torque the floor takes, known only
//! roughly, accelerates the robot the wheel rolls, and the wheel's controller takes the speed
//! it costs back. While the drive is saturated — a skid, a wheel unloaded as the robot pitches,
//! where the model knows least what the floor takes — a rate offset of standard deviation σ_k
//! [m/s] on the base's two horizontal positions and one of σ_t [rad/s] on its yaw, each the
//! same through a prediction (`uncertainty.saturation_slip`): the skid's slide and turn, which
//! last as long as the skid. And a slip noise σ_s [rad/√s] on the base's yaw
//! (`uncertainty.slip_noise`): the heading's random walk outside the constraints, which the
//! wheel controllers do not take back.
//!
//! σ_τ is the smallest value whose predicted covariance (the node's: propagated, error estimate
//! and floors, plus the reference's own) holds the target fraction of the predictions through
//! no saturation inside its 95 % region at every fit horizon (doubling, then bisection of log
//! σ_τ). σ_k and σ_t act on the predictions through a saturation: the pair with the lowest log
//! score among those that cover them as σ_τ covers the others. A coverage count alone would
//! take them up until the skids' errors in one direction fall inside a region grown in all;
//! the likelihood weighs the region's shape. σ_s, beside them, is the most likely value (the
//! lowest log score): the other terms may already cover the calibration drive's errors, which
//! the fit itself took down, while a fresh drive's heading drifts more. The searches:
//! noise_search.rs.
//!
//! On a scene with tyres σ_τ is not fitted: the tyres' grip rejects a wheel's own noise
//! ([`TYRES_REJECT_NOISE`]).
//!
//! Every trial is scored from one replay per term it moves (noise_basis.rs); the calibration's
//! last values are replayed once more and scored as `evaluate` would ([`rescore`]).

use super::noise_basis::{NoiseBasis, Scored, TERMS, Terms, replayed};
use super::{CalibrationError, CalibrationSettings, Problem};
use crate::replay::{EvaluationSettings, evaluate, stats::Coverage};
use nalgebra::Matrix3;
use search::{most_likely_skid, most_likely_slip, smallest_sigma};
use serde::Serialize;
use serde_yaml::Value;

/// The fitted process noise.
#[derive(Clone, Debug, Serialize)]
pub struct ProcessNoise {
    /// The joints it is on (the wheels').
    pub joints: Vec<String>,
    /// σ_τ [(N·m)/√Hz]: the effort noise.
    pub effort_noise: f64,
    /// The base's horizontal coordinates the skid's slide is on.
    pub saturation_slip_coordinates: Vec<String>,
    /// σ_k [m/s], while the drive is saturated: with σ_t, the lowest log score.
    pub saturation_slip: f64,
    /// σ_t [rad/s] on the yaw (`slip_coordinate`), while the drive is saturated.
    pub saturation_turn: f64,
    /// The base's yaw coordinate the slip noise is on, if the base has one.
    pub slip_coordinate: Option<String>,
    /// σ_s [rad/√s]: the yaw's random walk, the most likely value beside the others.
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
    /// Why σ_τ was not fitted, where it was not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_fitted: Option<&'static str>,
}

/// A tyre's grip ties its wheel to the floor at the tyre's slip rate (~10⁴ /s) and the wheel's
/// controller holds its speed: noise on a wheel is rejected within milliseconds and spreads no
/// pose (acceleration noise of 30 (rad/s²)/√Hz on the soft-floor robot's wheels moved
/// validation_smooth's mean NEES at 1 s from 4.3 to 4.1 only).
const TYRES_REJECT_NOISE: &str =
    "the tyres' grip and the wheel controllers reject noise on the wheels";

/// One trial's coverages (as [`ProcessNoise`] states them) and log score.
#[derive(Clone, Copy)]
struct Score {
    coverage_p95: f64,
    unsaturated_coverage_p95: f64,
    saturated_coverage_p95: f64,
    saturated: usize,
    log_score: f64,
}

/// Fits the process noise for the scene `yaml` (the fitted one) and writes it in; the skid's
/// slide and turn [σ_k, σ_t] searched for, or kept at `kept_skid` where given: the weighted
/// rounds keep them, so that the weights they set do not move them in turn (docs/logs.md).
/// Its coverages and log score are the sum's (noise_basis.rs; [`rescore`] replays them). With
/// it, every prediction's pose covariance plus its reference's under the noise found, in
/// [`Problem::errors`]' order: the weights of a weighted round (weighting.rs).
pub(super) fn fit(
    problem: &Problem,
    yaml: &mut Value,
    settings: &CalibrationSettings,
    kept_skid: Option<[f64; 2]>,
) -> Result<(ProcessNoise, Vec<Matrix3<f64>>), CalibrationError> {
    let replay = EvaluationSettings {
        propagate_covariance: true,
        ..settings.replay.clone()
    };
    // The fit owns its four terms: every trial and the result set them all, 0 included, so
    // that what is scored is what is written.
    let write = |yaml: &mut Value, [sigma, slide, turn, slip]: Terms| {
        (problem.places).set_wheel_noise(yaml, "effort_noise", sigma);
        (problem.places).set_skid_slide(yaml, slide);
        (problem.places).set_skid_turn(yaml, turn);
        (problem.places).set_yaw_slip(yaml, slip);
    };
    let joints = problem.places.wheel_joints().to_vec();
    let tyres = problem.places.tyres_carry_wheels();
    let searches_sigma = !(joints.is_empty() || tyres);
    // Every trial scored by the sum of the basis's covariances (noise_basis.rs), from a base
    // replay with a kept skid pair in it where no search of σ_τ scores trials without it: no
    // trial then moves the pair, and its two replays are saved.
    let at = match kept_skid {
        Some([slide, turn]) if !searches_sigma => [0.0, slide, turn, 0.0],
        _ => [0.0; TERMS],
    };
    let mut basis = NoiseBasis::new(problem, yaml, &write, replay, at)?;
    let horizons = basis.horizons();
    // [σ_τ, σ_k, σ_t, σ_s].
    let mut score = |terms: Terms| -> Result<Score, CalibrationError> {
        Ok(summary(basis.score(terms)?, horizons))
    };
    let target = settings.target_coverage_p95;
    let s0 = score(at)?;
    let (mut sigma, [_, mut slide, mut turn, _], mut s) = (0.0, at, s0);
    if !(s0.unsaturated_coverage_p95 >= target && s0.saturated_coverage_p95 >= target) {
        // σ_τ on the predictions only it acts on; then the skid's pair, beside it, on those
        // through a saturation.
        if searches_sigma {
            (sigma, s) = smallest_sigma(|sigma| score([sigma, 0.0, 0.0, 0.0]), target)?;
        }
        if s.saturated > 0 {
            (slide, turn, s) = match kept_skid {
                Some([k, t]) => (k, t, score([sigma, k, t, 0.0])?),
                None => most_likely_skid(
                    |slide, turn| score([sigma, slide, turn, 0.0]),
                    problem.places.base_horizontal().is_empty(),
                    problem.places.base_yaw().is_none(),
                    target,
                )?,
            };
        }
    }
    let mut slip = 0.0;
    if problem.places.base_yaw().is_some() {
        (slip, s) = most_likely_slip(|slip| score([sigma, slide, turn, slip]), s)?;
    }
    let terms = [sigma, slide, turn, slip];
    let covariances = basis.covariances(terms)?;
    let replays = basis.replays;
    write(yaml, terms);
    let noise = ProcessNoise {
        joints,
        effort_noise: sigma,
        saturation_slip_coordinates: problem.places.base_horizontal().to_vec(),
        saturation_slip: slide,
        saturation_turn: turn,
        slip_coordinate: problem.places.base_yaw().map(str::to_string),
        slip_noise: slip,
        coverage_p95: s.coverage_p95,
        unsaturated_coverage_p95: s.unsaturated_coverage_p95,
        saturated_coverage_p95: s.saturated_coverage_p95,
        saturated_predictions: s.saturated,
        log_score: s.log_score,
        replays,
        not_fitted: tyres.then_some(TYRES_REJECT_NOISE),
    };
    Ok((noise, covariances))
}

/// The coverages and log score of `scored`, over `horizons` fit horizons.
fn summary(scored: Vec<Scored>, horizons: usize) -> Score {
    let (mut nees, mut log_score) = (Vec::new(), 0.0);
    let (mut saturated, mut unsaturated) = (vec![vec![]; horizons], vec![vec![]; horizons]);
    for p in scored {
        log_score += 0.5 * p.nees + p.half_log_det;
        nees.push(p.nees);
        if p.saturated {
            saturated[p.horizon].push(p.nees);
        } else {
            unsaturated[p.horizon].push(p.nees);
        }
    }
    // A subset's coverage at the horizon where it is least.
    let least = |by_horizon: &[Vec<f64>]| {
        (by_horizon.iter())
            .filter(|n| !n.is_empty())
            .map(|n| Coverage::of(n).p95)
            .fold(1.0, f64::min)
    };
    Score {
        coverage_p95: if nees.is_empty() {
            0.0
        } else {
            Coverage::of(&nees).p95
        },
        unsaturated_coverage_p95: least(&unsaturated),
        saturated_coverage_p95: least(&saturated),
        saturated: saturated.iter().map(Vec::len).sum(),
        log_score: log_score / nees.len().max(1) as f64,
    }
}

/// Replays the scene `yaml` (the fitted values and `noise` written in) and states `noise`'s
/// coverages and log score as that replay has them, not as the sum does.
pub(super) fn rescore(
    problem: &Problem,
    yaml: &Value,
    settings: &CalibrationSettings,
    noise: &mut ProcessNoise,
) -> Result<(), CalibrationError> {
    let replay = EvaluationSettings {
        propagate_covariance: true,
        ..settings.replay.clone()
    };
    let scene = problem.source.build(yaml)?;
    let mut records = Vec::new();
    for recording in problem.recordings {
        records.extend(evaluate(&scene, recording, &replay)?.records);
    }
    let s = summary(
        replayed(&records, &replay.horizons_s),
        replay.horizons_s.len(),
    );
    noise.coverage_p95 = s.coverage_p95;
    noise.unsaturated_coverage_p95 = s.unsaturated_coverage_p95;
    noise.saturated_coverage_p95 = s.saturated_coverage_p95;
    noise.saturated_predictions = s.saturated;
    noise.log_score = s.log_score;
    noise.replays += 1;
    Ok(())
}

#[path = "noise_search.rs"]
mod search;
