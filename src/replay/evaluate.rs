//! How well a scene predicts a recorded drive: from start times t0 every `every` seconds, one
//! prediction per horizon h, as the predictor node makes it (start state: start.rs; the arm held
//! where it is; the scene's integration settings; a start refused by the error bound rerun
//! without it and counted), under the recorded commands over [t0, t0 + h], compared with the
//! last reference pose at or before t0 + h (no interpolation).
//!
//! The predicted covariance is the node's: the propagated one, plus on each pose axis the
//! integration error estimate and the floors in quadrature (nodes/src/predictor/mod.rs). Each
//! prediction's NEES is taken against it plus the reference's own covariance (stats.rs).

use super::ReplayError;
use super::replayer::{Replayer, Span};
use super::series::{Nanos, Odometry, Recording, show_stamp};
use super::stats::{Coverage, Spread, nees};
use crate::Scene;
use crate::model::base_covariance::{JointSigma, odometry_covariance};
use crate::model::{BasePose, Model};
use serde::Serialize;

/// The predictor node's covariance floors (`cd_predictor` `covariance.*_floor`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CovarianceFloors {
    /// σ added in quadrature to x and y [m].
    pub position_m: f64,
    /// σ added in quadrature to yaw [rad].
    pub orientation_rad: f64,
}

impl Default for CovarianceFloors {
    /// The node's defaults (params/default.yaml).
    fn default() -> Self {
        CovarianceFloors {
            position_m: 1e-3,
            orientation_rad: 1e-3,
        }
    }
}

/// What an evaluation does.
#[derive(Clone, Debug)]
pub struct EvaluationSettings {
    /// Horizons [s], each > 0.
    pub horizons_s: Vec<f64>,
    /// Period of the start times [s].
    pub every_s: f64,
    /// The predicted covariance's floors.
    pub floors: CovarianceFloors,
    /// Every 1-DOF joint's state noise (the node's `state.joint_noise`, default 0).
    pub joint_noise: JointSigma,
    /// Propagate the start covariance (the node's `covariance.propagate`); false: floors only.
    pub propagate_covariance: bool,
    /// A command older than this at t0 is stale and the node's `hold` fallback applies [s].
    pub command_timeout_s: f64,
    /// The longest gap allowed in the state inputs and the reference [s].
    pub max_gap_s: f64,
    /// Start each velocity controller's integral where its recorded effort puts it (the
    /// node's `state.controller_integrals_from_effort`); false (default): at zero.
    pub integrals_from_efforts: bool,
    /// Threads the starts are replayed on (default: the cores available); the figures do not
    /// depend on it.
    pub threads: usize,
}

impl Default for EvaluationSettings {
    fn default() -> Self {
        EvaluationSettings {
            horizons_s: vec![0.25, 0.5, 1.0, 2.0],
            every_s: 0.5,
            floors: CovarianceFloors::default(),
            joint_noise: JointSigma::default(),
            propagate_covariance: true,
            command_timeout_s: 0.5,
            max_gap_s: 0.5,
            integrals_from_efforts: false,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        }
    }
}

/// One prediction and its score. Poses are (x [m], y [m], yaw [rad]) in the world (odom)
/// frame; covariances 3 × 3 over them.
#[derive(Clone, Debug, Serialize)]
pub struct PredictionRecord {
    /// Start [s from the recording's start].
    pub t0_s: f64,
    /// Horizon [s].
    pub horizon_s: f64,
    /// The error bound refused it; rerun without the bound.
    pub refused: bool,
    /// Time a velocity controller spent saturated over the horizon [s]
    /// (`Trajectory::saturated_s`).
    pub saturated_s: f64,
    /// Predicted pose at t0 + h.
    pub predicted: [f64; 3],
    /// Its covariance (propagated, error estimate and floors).
    pub predicted_covariance: [[f64; 3]; 3],
    /// Time of the reference pose [s from the recording's start] (≤ t0 + h).
    pub reference_t_s: f64,
    /// The reference pose.
    pub reference: [f64; 3],
    /// Its own covariance.
    pub reference_covariance: [[f64; 3]; 3],
    /// Distance between the positions [m].
    pub position_error_m: f64,
    /// Reference yaw − predicted yaw, wrapped to (−π, π] [rad].
    pub yaw_error_rad: f64,
    /// eᵀ (P_predicted + P_reference)⁻¹ e, e = reference − predicted (yaw wrapped).
    pub nees: f64,
}

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
    /// Fractions inside the 50 % and 95 % regions.
    pub coverage: Coverage,
    /// Mean NEES (3 when the covariance is right).
    pub nees_mean: f64,
}

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

pub(super) fn to_nanos(s: f64) -> Nanos {
    (s * 1e9).round() as Nanos
}

/// (x, y, yaw) of a base pose.
fn planar(p: &BasePose) -> [f64; 3] {
    let [x, y, z, w] = p.orientation_xyzw;
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    [p.position[0], p.position[1], yaw]
}

/// The (x, y, yaw) block of a REP-103 6 × 6 pose covariance.
fn planar_block(c: &[f64; 36]) -> [[f64; 3]; 3] {
    const IDX: [usize; 3] = [0, 1, 5];
    IDX.map(|i| IDX.map(|j| 0.5 * (c[6 * i + j] + c[6 * j + i])))
}

fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}

fn check_settings(s: &EvaluationSettings) -> Result<(), ReplayError> {
    let bad = |what: &str, x: f64| ReplayError::Settings(format!("{what} = {x}: {WHY}"));
    const WHY: &str = "must be positive and finite";
    if s.horizons_s.is_empty() {
        return Err(ReplayError::Settings("no horizon given".into()));
    }
    if s.threads == 0 {
        return Err(ReplayError::Settings(
            "threads = 0: must be at least 1".into(),
        ));
    }
    for &h in &s.horizons_s {
        if !(h.is_finite() && h > 0.0) {
            return Err(bad("horizon [s]", h));
        }
    }
    for (what, x) in [
        ("every [s]", s.every_s),
        ("command timeout [s]", s.command_timeout_s),
        ("max gap [s]", s.max_gap_s),
    ] {
        if !(x.is_finite() && x > 0.0) {
            return Err(bad(what, x));
        }
    }
    let f = &s.floors;
    let j = &s.joint_noise;
    for (what, x) in [
        ("position floor [m]", f.position_m),
        ("orientation floor [rad]", f.orientation_rad),
        ("joint position noise [rad or m]", j.position),
        ("joint velocity noise [rad/s or m/s]", j.velocity),
    ] {
        if !(x.is_finite() && x >= 0.0) {
            return Err(ReplayError::Settings(format!(
                "{what} = {x}: must be ≥ 0 and finite"
            )));
        }
    }
    Ok(())
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
    summarise(settings, starts.len(), records, (end - first) as f64 * 1e-9)
}

/// A start's index and its predictions (or why it failed).
type StartRecords = (usize, Result<Vec<PredictionRecord>, ReplayError>);

/// A prediction's last sample (q, its covariance, its error estimate) against a reference.
pub(super) fn score(
    model: &Model,
    (q, covariance, error_estimate): (&[f64], Option<&[Vec<f64>]>, f64),
    reference: &Odometry,
    floors: CovarianceFloors,
) -> Option<PredictionRecord> {
    let predicted = planar(&model.base_pose(q));
    let mut p = match covariance {
        Some(c) => planar_block(&odometry_covariance(model, q, c).0),
        None => [[0.0; 3]; 3],
    };
    let sp = error_estimate.hypot(floors.position_m);
    let so = error_estimate.hypot(floors.orientation_rad);
    for (i, s) in [sp, sp, so].into_iter().enumerate() {
        p[i][i] += s * s;
    }
    let r = planar(&reference.pose);
    let rc = planar_block(&reference.pose_covariance);
    let e = [
        r[0] - predicted[0],
        r[1] - predicted[1],
        wrap(r[2] - predicted[2]),
    ];
    let sum = [0, 1, 2].map(|i| [0, 1, 2].map(|j| p[i][j] + rc[i][j]));
    Some(PredictionRecord {
        t0_s: 0.0,
        horizon_s: 0.0,
        refused: false,
        saturated_s: 0.0,
        predicted,
        predicted_covariance: p,
        reference_t_s: 0.0,
        reference: r,
        reference_covariance: rc,
        position_error_m: e[0].hypot(e[1]),
        yaw_error_rad: e[2],
        nees: nees(e, sum)?,
    })
}

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
            coverage: Coverage::of(&nees),
            nees_mean: nees.iter().sum::<f64>() / nees.len() as f64,
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
