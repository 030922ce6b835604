//! The fit's residual function: the replayed predictions' errors at trial values of the
//! fitted parameters, normalised or whitened, and which start each belongs to.

use super::{CalibrationError, FitParameter, SceneParameters, SceneSource};
use crate::replay::{EvaluationSettings, Recording, evaluate};
use nalgebra::{DVector, Matrix3, Vector3};
use serde_yaml::Value;
use std::cell::{Cell, RefCell};
use std::collections::VecDeque;

/// A prediction's start: (recording, the start's rank in it).
pub(super) type Start = (usize, usize);
/// A prediction's (horizon index, [Δx, Δy, Δyaw]).
pub(super) type HorizonError = (usize, [f64; 3]);

/// The fit's residual function over the fitted parameters.
pub(crate) struct Problem<'a> {
    pub(super) source: &'a SceneSource<'a>,
    pub(super) places: SceneParameters,
    pub(super) recordings: &'a [Recording],
    pub(super) replay: EvaluationSettings,
    /// The fitted parameters with their scene values and scales.
    pub(super) fitted: Vec<(FitParameter, f64, f64)>,
    /// Per horizon, the RMS of the position and the yaw errors at the scene's values.
    pub(super) norms: Vec<[f64; 2]>,
    /// Per prediction, the inverse Cholesky factor of its predicted pose covariance (with the
    /// fitted process noise): where present, a prediction's residual is its whitened error
    /// instead of its error over the horizon's RMS (weighting.rs).
    pub(super) whitening: Option<Vec<Matrix3<f64>>>,
    /// Per residual row, its prediction's start: (recording, the start's rank in it).
    pub(super) starts: Vec<Start>,
    pub(super) count: usize,
    /// The errors of the scenes replayed last, by the fitted values' bits: a weighted round
    /// starts where the last fit ended, and its first residuals and Jacobian are that fit's
    /// last ones under new weights, which the errors do not depend on.
    pub(super) replayed: RefCell<ErrorCache>,
    /// Replays of every recording so far.
    pub(super) replays: Cell<usize>,
}

/// The fitted values a replay ran at: each parameter with its value's bits.
type FittedBits = Vec<(FitParameter, u64)>;

/// The errors of recently replayed fitted values (at most [`ErrorCache::CAPACITY`]).
#[derive(Default)]
pub(crate) struct ErrorCache {
    entries: VecDeque<(FittedBits, Vec<(Start, HorizonError)>)>,
}

impl ErrorCache {
    /// A Jacobian's columns with its centre, and a few more.
    const CAPACITY: usize = 24;

    fn get(&self, key: &FittedBits) -> Option<&Vec<(Start, HorizonError)>> {
        (self.entries.iter())
            .find(|(k, _)| k == key)
            .map(|(_, e)| e)
    }

    fn insert(&mut self, key: FittedBits, errors: Vec<(Start, HorizonError)>) {
        if self.entries.len() == Self::CAPACITY {
            self.entries.pop_front();
        }
        self.entries.push_back((key, errors));
    }
}

impl Problem<'_> {
    /// The scene file with scaled offsets `x` written in.
    pub(super) fn yaml_at(&self, x: &[f64]) -> Value {
        let mut yaml = self.source.yaml.clone();
        for ((p, value, scale), xi) in self.fitted.iter().zip(x) {
            self.places.set(&mut yaml, *p, value + scale * xi);
        }
        yaml
    }

    /// Every prediction's (horizon index, Δx, Δy, Δyaw) at scaled offsets `x`.
    pub(super) fn errors(&self, x: &[f64]) -> Result<Vec<HorizonError>, CalibrationError> {
        Ok(self
            .errors_by_start(x)?
            .into_iter()
            .map(|(_, e)| e)
            .collect())
    }

    /// [`Self::errors`], each with its start: (recording, the start's rank in it).
    pub(super) fn errors_by_start(
        &self,
        x: &[f64],
    ) -> Result<Vec<(Start, HorizonError)>, CalibrationError> {
        let key: FittedBits = (self.fitted.iter().zip(x))
            .map(|((p, value, scale), xi)| (*p, (value + scale * xi).to_bits()))
            .collect();
        if let Some(errors) = self.replayed.borrow().get(&key) {
            return Ok(errors.clone());
        }
        let errors = self.replay_errors(x)?;
        self.replayed.borrow_mut().insert(key, errors.clone());
        Ok(errors)
    }

    /// The replays' errors at `x` (module documentation).
    fn replay_errors(&self, x: &[f64]) -> Result<Vec<(Start, HorizonError)>, CalibrationError> {
        let scene = self.source.build(&self.yaml_at(x))?;
        self.replays.set(self.replays.get() + 1);
        let mut out = Vec::new();
        for (n, recording) in self.recordings.iter().enumerate() {
            let mut t0s: Vec<f64> = Vec::new();
            let ev = evaluate(&scene, recording, &self.replay)?;
            for r in &ev.records {
                let k = (self.replay.horizons_s.iter())
                    .position(|&h| h == r.horizon_s)
                    .unwrap_or(0);
                let e = [
                    r.reference[0] - r.predicted[0],
                    r.reference[1] - r.predicted[1],
                    r.yaw_error_rad,
                ];
                let rank = match t0s.iter().position(|&t| t == r.t0_s) {
                    Some(rank) => rank,
                    None => {
                        t0s.push(r.t0_s);
                        t0s.len() - 1
                    }
                };
                out.push(((n, rank), (k, e)));
            }
        }
        Ok(out)
    }

    /// How many start periods apart two predictions may still share an error: their windows
    /// overlap, or one's reference is the other's start.
    pub(super) fn lags(&self) -> usize {
        let longest = self.replay.horizons_s.iter().copied().fold(0.0, f64::max);
        (longest / self.replay.every_s.max(1e-9) + 1e-9).floor() as usize
    }

    pub(super) fn residual_count(&self) -> usize {
        self.count
    }

    /// The normalised residuals at scaled offsets `x`.
    pub(super) fn residuals(&self, x: &[f64]) -> Result<DVector<f64>, CalibrationError> {
        let errors = self.errors(x)?;
        if 3 * errors.len() != self.count {
            return Err(CalibrationError::Scene(format!(
                "the replay scored {} predictions at a trial value, {} at the scene's",
                errors.len(),
                self.count / 3
            )));
        }
        let mut r = DVector::zeros(self.count);
        for (i, (k, e)) in errors.iter().enumerate() {
            let w = match &self.whitening {
                Some(w) => w[i] * Vector3::from(*e),
                None => {
                    let [np, ny] = self.norms[*k];
                    Vector3::new(e[0] / np, e[1] / np, e[2] / ny)
                }
            };
            r.fixed_rows_mut::<3>(3 * i).copy_from(&w);
        }
        Ok(r)
    }
}

/// Where the fit starts (scaled offsets): the scene's
/// values, except where the scene's value is an edge with no slope to follow, where the start
/// is the best of a coarse scan. A clamp (the traction torque) only acts below where it is, and
/// one the drives never reach changes nothing: scanned down to a quarter of its value. A rigid
/// contact (no sideways creep) is the edge of `lateral_creep`: scanned up to 4 mm/s per newton.
pub(super) fn start(problem: &Problem) -> Result<DVector<f64>, CalibrationError> {
    let mut x0 = DVector::zeros(problem.fitted.len());
    for (k, (p, value, scale)) in problem.fitted.iter().enumerate() {
        let tried: Vec<f64> = match p {
            FitParameter::TractionTorque => [1.0, 0.8, 0.6, 0.45, 0.35, 0.25]
                .iter()
                .map(|fraction| (fraction - 1.0) * value / scale)
                .collect(),
            FitParameter::LateralCreep if *value == 0.0 => vec![0.0, 0.5, 1.0, 2.0, 4.0],
            _ => continue,
        };
        let mut best = (f64::INFINITY, 0.0);
        for xk in tried {
            let mut x = x0.clone();
            x[k] = xk;
            let cost = problem.residuals(x.as_slice())?.norm_squared();
            if cost < best.0 {
                best = (cost, x[k]);
            }
        }
        x0[k] = best.1;
    }
    Ok(x0)
}
