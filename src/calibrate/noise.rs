//! The process noise: what the model still misses after the fit, stated as the wheels'
//! acceleration noise so that the predicted covariance covers it.
//!
//! One density σ [(rad/s²)/√Hz] on every wheel joint (`uncertainty.acceleration_noise`,
//! docs/propagation.md): through the rolling constraints it spreads the base's position along
//! the travel and its yaw, growing with the horizon. σ is the smallest value whose predicted
//! covariance (the node's: propagated, error estimate and floors, plus the reference's own)
//! holds the target fraction of the replayed errors inside its 95 % region, pooled over every
//! horizon and recording; found by doubling, then bisection of log σ. Not on a scene with tyres:
//! their grip rejects such noise ([`TYRES_REJECT_NOISE`]).

use super::{CalibrationError, CalibrationSettings, Problem};
use crate::replay::{EvaluationSettings, evaluate, stats::Coverage};
use serde::Serialize;
use serde_yaml::Value;

/// The fitted process noise.
#[derive(Clone, Debug, Serialize)]
pub struct ProcessNoise {
    /// The joints it is on (the wheels').
    pub joints: Vec<String>,
    /// σ [(rad/s²)/√Hz].
    pub acceleration_noise: f64,
    /// The fraction of the replayed errors inside the 95 % region with it.
    pub coverage_p95: f64,
    /// Replays it took.
    pub replays: usize,
    /// Why σ was not fitted, where it was not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_fitted: Option<&'static str>,
}

/// A tyre's grip ties its wheel to the floor at the tyre's slip rate (~10⁴ /s) and the wheel's
/// controller holds its speed: acceleration noise on a wheel (or on the base) is rejected
/// within milliseconds and spreads no pose (σ = 30 (rad/s²)/√Hz on the soft-floor robot's
/// wheels moved validation_smooth's mean NEES at 1 s from 32 to 28).
const TYRES_REJECT_NOISE: &str =
    "the tyres' grip and the wheel controllers reject acceleration noise on the wheels";

/// Bisection steps of log σ after the bracket: the bracket's factor 2 to 2^(1/64).
const BISECTIONS: usize = 6;
/// The largest and smallest σ tried [(rad/s²)/√Hz].
const LARGEST: f64 = 1e4;
const SMALLEST: f64 = 1e-4;

/// Fits σ for the scene `yaml` (the fitted one) and writes it in.
pub(super) fn fit(
    problem: &Problem,
    yaml: &mut Value,
    settings: &CalibrationSettings,
) -> Result<ProcessNoise, CalibrationError> {
    let replay = EvaluationSettings {
        propagate_covariance: true,
        ..settings.replay.clone()
    };
    let mut replays = 0;
    let mut coverage = |sigma: f64| -> Result<f64, CalibrationError> {
        let mut trial = yaml.clone();
        if sigma > 0.0 {
            problem.places.set_wheel_noise(&mut trial, sigma);
        }
        let scene = problem.source.build(&trial)?;
        let mut nees = Vec::new();
        for recording in problem.recordings {
            let ev = evaluate(&scene, recording, &replay)?;
            nees.extend(ev.records.iter().map(|r| r.nees));
        }
        replays += 1;
        Ok(if nees.is_empty() {
            0.0
        } else {
            Coverage::of(&nees).p95
        })
    };
    let target = settings.target_coverage_p95;
    let joints = problem.places.wheel_joints().to_vec();
    let c0 = coverage(0.0)?;
    let tyres = problem.places.has_tyres();
    if c0 >= target || joints.is_empty() || tyres {
        return Ok(ProcessNoise {
            joints,
            acceleration_noise: 0.0,
            coverage_p95: c0,
            replays,
            not_fitted: (tyres && c0 < target).then_some(TYRES_REJECT_NOISE),
        });
    }
    // A bracket [lo, hi] with coverage(lo) < target ≤ coverage(hi), by factors of 2 from
    // 0.1 (wheel accelerations of a tenth of a rad/s² over a second's horizon).
    let (mut lo, mut hi) = (0.0, 0.1);
    let mut c_hi = coverage(hi)?;
    if c_hi >= target {
        lo = hi / 2.0;
        while lo > SMALLEST {
            let c = coverage(lo)?;
            if c < target {
                break;
            }
            (hi, c_hi) = (lo, c);
            lo /= 2.0;
        }
    } else {
        while c_hi < target && hi < LARGEST {
            lo = hi;
            hi *= 2.0;
            c_hi = coverage(hi)?;
        }
    }
    for _ in 0..BISECTIONS {
        let mid = (lo * hi).sqrt();
        let c = coverage(mid)?;
        if c >= target {
            (hi, c_hi) = (mid, c);
        } else {
            lo = mid;
        }
    }
    problem.places.set_wheel_noise(yaml, hi);
    Ok(ProcessNoise {
        joints,
        acceleration_noise: hi,
        coverage_p95: c_hi,
        replays,
        not_fitted: None,
    })
}
