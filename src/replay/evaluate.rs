//! How well a scene predicts a recorded drive: from start times t0 every `every` seconds, one
//! prediction per horizon h, as the predictor node makes it (start state: start.rs; the arm held
//! where it is; the scene's integration settings; a start refused by the error bound rerun
//! without it and counted), under the recorded commands over [t0, t0 + h], compared with the
//! last reference pose at or before t0 + h (no interpolation), the prediction taken at that
//! pose's own stamp.
//!
//! The predicted covariance is the node's: the propagated one, plus on each pose axis the
//! integration error estimate and the floors in quadrature (nodes/src/predictor/mod.rs). Each
//! prediction's NEES is taken against it plus the reference's own covariance (stats.rs).
//!
//! Per horizon, the predictions whose command held over the horizon also give the drive's
//! response, as the node's monitor fits it (`monitor::ResponseWindow`): how much later than
//! the model the drive reaches its commands, and how far it travels and turns beyond them.

use super::ReplayError;
use super::record::{EvaluationSettings, PredictionRecord, check_settings, to_nanos};
use super::replayer::{Replayer, Span};
use super::series::{Nanos, Recording, show_stamp};
use super::stats::{Coverage, Spread};
use crate::Scene;
use crate::monitor::{ResponseFit, ResponseWindow, ScoredResponse};
use serde::Serialize;

/// The figures of one horizon.
#[derive(Clone, Debug, Serialize)]
pub struct HorizonSummary {
    /// Horizon [s].
    pub horizon_s: f64,
    /// Predictions scored.
    pub predictions: usize,
    /// Of which refused by the error bound (and rerun without it).
    pub refused: usize,
    /// Position error [m].
    pub position_error_m: Spread,
    /// |yaw error| [rad].
    pub yaw_error_rad: Spread,
    /// Fractions inside the 50 % and 95 % regions, with their 95 % intervals.
    pub coverage: Coverage,
    /// Mean NEES (3 when the covariance is right).
    pub nees_mean: f64,
    /// The drive's response over the predictions whose command held (absent where they do
    /// not determine it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub response: Option<ResponseFit>,
}

/// A command that moves off the one at a start by more than this (v [m/s], ω [rad/s]) within
/// the horizon leaves the prediction out of the response (the node's
/// `monitor.command_tolerance` default).
const COMMAND_TOLERANCE: [f64; 2] = [0.005, 0.01];

/// An evaluation: the summary per horizon and every prediction.
#[derive(Clone, Debug, Serialize)]
pub struct Evaluation {
    /// Predictions scored (starts × the horizons each fits in the recording).
    pub predictions: usize,
    /// Of which refused by the error bound.
    pub refused: usize,
    /// Start times.
    pub starts: usize,
    /// Per horizon, in the order asked.
    pub horizons: Vec<HorizonSummary>,
    /// Every prediction, by start then horizon.
    #[serde(skip)]
    pub records: Vec<PredictionRecord>,
}

/// Evaluates `scene` on `recording` (module documentation).
pub fn evaluate(
    scene: &Scene,
    recording: &Recording,
    settings: &EvaluationSettings,
) -> Result<Evaluation, ReplayError> {
    check_settings(settings)?;
    recording.check(to_nanos(settings.max_gap_s))?;
    let origin = recording.origin();
    let (reference_begin, end) = recording.reference.span()?;
    // The first odometry once the joint states and the reference have begun: the starts fall
    // on odometry stamps, and every one has a reference at or before its horizons.
    let (joints_begin, _) = recording.joint_states.span()?;
    let begin = joints_begin.max(reference_begin);
    let odom = &recording.odometry;
    let first = odom.samples[odom.samples.partition_point(|(t, _)| *t < begin)..]
        .first()
        .map(|s| s.0)
        .ok_or_else(|| ReplayError::NoStart {
            series: odom.name.clone(),
            at_s: (begin - origin) as f64 * 1e-9,
            stamp: show_stamp(begin),
        })?;
    let every = to_nanos(settings.every_s).max(1);
    let shortest = settings.horizons_s.iter().copied().fold(f64::MAX, f64::min);
    let starts: Vec<Nanos> = std::iter::successors(Some(first), |t| Some(t + every))
        .take_while(|t0| t0 + to_nanos(shortest) <= end)
        .collect();
    let span = Span { origin, end };
    let threads = settings.threads.clamp(1, starts.len().max(1));
    // Each thread replays every `threads`-th start with its own predictor, in order, and
    // stops at its first error: every start before the earliest error is replayed, so the
    // error reported is the one a replay in order meets first.
    let per_thread: Vec<Vec<StartRecords>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|k| {
                let starts = &starts;
                s.spawn(move || {
                    let mut out = Vec::new();
                    let mut replayer = match Replayer::new(scene, recording, settings, span) {
                        Ok(r) => r,
                        Err(e) => return vec![(k, Err(e))],
                    };
                    for i in (k..starts.len()).step_by(threads) {
                        let r = replayer.start(starts[i]);
                        let failed = r.is_err();
                        out.push((i, r));
                        if failed {
                            break;
                        }
                    }
                    out
                })
            })
            .collect();
        (handles.into_iter())
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    let mut by_start: Vec<StartRecords> = per_thread.into_iter().flatten().collect();
    by_start.sort_by_key(|(i, _)| *i);
    let mut records = Vec::new();
    for (_, r) in by_start {
        records.extend(r?);
    }
    let mut evaluation = summarise(settings, starts.len(), records, (end - first) as f64 * 1e-9)?;
    for h in &mut evaluation.horizons {
        h.response = response(recording, &evaluation.records, h.horizon_s);
    }
    Ok(evaluation)
}

/// The drive's response at horizon `h` [s] over `records` (module documentation).
fn response(recording: &Recording, records: &[PredictionRecord], h: f64) -> Option<ResponseFit> {
    let origin = recording.origin();
    let of_h = || records.iter().filter(|r| r.horizon_s == h);
    let mut window = ResponseWindow::new(of_h().count());
    for r in of_h() {
        let t0 = origin + to_nanos(r.t0_s);
        let (Some((_, command)), Some((_, odom))) = (
            recording.commands.at_or_before(t0),
            recording.odometry.at_or_before(t0),
        ) else {
            continue;
        };
        let later = recording.commands.between(t0, t0 + to_nanos(h));
        let moved = |c: &[f64; 2]| (0..2).any(|k| (c[k] - command[k]).abs() > COMMAND_TOLERANCE[k]);
        if later.iter().any(|(_, c)| moved(c)) {
            continue;
        }
        let (p, rc) = (&r.predicted_covariance, &r.reference_covariance);
        let covariance = [0, 1, 2].map(|i| [0, 1, 2].map(|j| p[i][j] + rc[i][j]));
        let e = [0, 1].map(|k| r.reference[k] - r.predicted[k]);
        window.push(&ScoredResponse {
            error: [e[0], e[1], r.yaw_error_rad],
            predicted_yaw: r.predicted[2],
            covariance: &covariance,
            command: *command,
            start_velocity: [odom.twist.linear[0], odom.twist.angular[2]],
            horizon: h,
        });
    }
    window.fit()
}

/// A start's index and its predictions (or why it failed).
type StartRecords = (usize, Result<Vec<PredictionRecord>, ReplayError>);

fn summarise(
    settings: &EvaluationSettings,
    starts: usize,
    records: Vec<PredictionRecord>,
    length_s: f64,
) -> Result<Evaluation, ReplayError> {
    let mut horizons = Vec::new();
    for &h in &settings.horizons_s {
        let of_h: Vec<&PredictionRecord> = records.iter().filter(|r| r.horizon_s == h).collect();
        if of_h.is_empty() {
            return Err(ReplayError::Settings(format!(
                "horizon {h} s: the recording's {length_s:.3} s after its first start leave no \
                 prediction of that horizon"
            )));
        }
        let pos: Vec<f64> = of_h.iter().map(|r| r.position_error_m).collect();
        let yaw: Vec<f64> = of_h.iter().map(|r| r.yaw_error_rad.abs()).collect();
        let nees: Vec<f64> = of_h.iter().map(|r| r.nees).collect();
        horizons.push(HorizonSummary {
            horizon_s: h,
            predictions: of_h.len(),
            refused: of_h.iter().filter(|r| r.refused).count(),
            position_error_m: Spread::of(&pos),
            yaw_error_rad: Spread::of(&yaw),
            coverage: Coverage::of_overlapping(&nees, settings.every_s, h),
            nees_mean: nees.iter().sum::<f64>() / nees.len() as f64,
            response: None,
        });
    }
    Ok(Evaluation {
        predictions: records.len(),
        refused: records.iter().filter(|r| r.refused).count(),
        starts,
        horizons,
        records,
    })
}
