//! One prediction's record: the settings a drive is replayed under, and how a prediction's last
//! sample is scored against the reference pose (evaluate.rs drives the replay, replayer.rs
//! makes the predictions).

use super::ReplayError;
use super::series::{Nanos, Odometry};
use super::stats::nees;
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
    /// Run the integration's error estimate, as the node does (default true). False: the
    /// predictions alone, at half the cost or less, none refused and no estimate in the
    /// covariance — for replays that use only the errors (the fit's residuals, calibrate/).
    pub error_estimate: bool,
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
            error_estimate: true,
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

pub(super) fn check_settings(s: &EvaluationSettings) -> Result<(), ReplayError> {
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
