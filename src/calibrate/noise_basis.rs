//! The process noise's terms scored without replaying the drives for every trial.
//!
//! The four terms (noise.rs) change the predicted covariance only: the predictions' states,
//! their integration error estimates, their saturations and the floors do not depend on them,
//! and the covariance is propagated linearly along the fixed trajectory (docs/propagation.md)
//! with the terms' variances entering additively. So a prediction's pose covariance is
//! P(σ) = P(β) + Σᵢ ((σᵢ² − βᵢ²) / uᵢ²) Rᵢ, where P(β) is the covariance at the basis's own
//! terms β (none, or the skid's pair a weighted round keeps; with the start's propagated, the
//! error estimate, the floors and the reference's own) and Rᵢ what term i adds at its unit
//! value uᵢ. One replay at β and one per term a trial moves off β give every trial's NEES and
//! log score by this sum, and the sum's covariances at the values found are what the next
//! weighted round weighs by; the calibration's last values are replayed once more and scored
//! directly ([`replayed`]).

use super::{CalibrationError, Problem};
use crate::replay::{EvaluationSettings, PredictionRecord, evaluate};
use nalgebra::{Matrix3, Vector3};
use serde_yaml::Value;

/// The terms' unit values [σ_τ (N·m)/√Hz, σ_k m/s, σ_t rad/s, σ_s rad/√s]: inside the
/// ranges the searches try, so that Rᵢ = P(uᵢ) − P₀ keeps its digits.
const UNITS: [f64; TERMS] = [0.01, 0.1, 0.1, 0.01];

/// The process noise's terms.
pub(super) const TERMS: usize = 4;
/// A value of each: [σ_τ, σ_k, σ_t, σ_s].
pub(super) type Terms = [f64; TERMS];

/// One prediction as the searches score it.
struct Prediction {
    /// Its horizon's index among the replay's horizons.
    horizon: usize,
    /// A velocity controller saturated over it.
    saturated: bool,
    /// reference − predicted (x [m], y [m], yaw [rad], wrapped).
    error: Vector3<f64>,
    /// P₀ plus the reference's own covariance.
    base: Matrix3<f64>,
}

/// A trial's NEES and log score per prediction, with what [`Prediction`] says of it.
pub(super) struct Scored {
    pub horizon: usize,
    pub saturated: bool,
    pub nees: f64,
    /// ½ ln det of the prediction's covariance plus the reference's.
    pub half_log_det: f64,
}

/// The predictions without process noise, and per term, once asked for, what its unit value
/// adds to each.
pub(super) struct NoiseBasis<'a> {
    problem: &'a Problem<'a>,
    yaml: Value,
    write: &'a dyn Fn(&mut Value, Terms),
    replay: EvaluationSettings,
    /// The terms the base replay ran at (β).
    at: Terms,
    predictions: Vec<Prediction>,
    per_unit: [Option<Vec<Matrix3<f64>>>; TERMS],
    /// Replays of every recording it took.
    pub replays: usize,
}

impl<'a> NoiseBasis<'a> {
    /// Replays `problem`'s recordings under the scene `yaml` with the terms at `at` (`write`
    /// sets the terms in a scene file).
    pub fn new(
        problem: &'a Problem<'a>,
        yaml: &Value,
        write: &'a dyn Fn(&mut Value, Terms),
        replay: EvaluationSettings,
        at: Terms,
    ) -> Result<Self, CalibrationError> {
        let mut basis = NoiseBasis {
            problem,
            yaml: yaml.clone(),
            write,
            replay,
            at,
            predictions: Vec::new(),
            per_unit: Default::default(),
            replays: 0,
        };
        let records = basis.records(at)?;
        basis.predictions = (records.iter())
            .map(|r| Prediction {
                horizon: horizon_index(&basis.replay.horizons_s, r),
                saturated: r.saturated_s > 0.0,
                error: Vector3::new(
                    r.reference[0] - r.predicted[0],
                    r.reference[1] - r.predicted[1],
                    r.yaw_error_rad,
                ),
                base: total(r),
            })
            .collect();
        Ok(basis)
    }

    /// The horizons' count.
    pub fn horizons(&self) -> usize {
        self.replay.horizons_s.len()
    }

    /// Every prediction's record under the scene with `terms` written in.
    fn records(&mut self, terms: Terms) -> Result<Vec<PredictionRecord>, CalibrationError> {
        let mut trial = self.yaml.clone();
        (self.write)(&mut trial, terms);
        let scene = self.problem.source.build(&trial)?;
        let mut out = Vec::new();
        for recording in self.problem.recordings {
            out.extend(evaluate(&scene, recording, &self.replay)?.records);
        }
        self.replays += 1;
        Ok(out)
    }

    /// Every prediction scored with `terms` by the sum.
    pub fn score(&mut self, terms: Terms) -> Result<Vec<Scored>, CalibrationError> {
        let covariances = self.covariances(terms)?;
        Ok((self.predictions.iter().zip(covariances))
            .map(|(p, c)| {
                let (nees, half_log_det) = match (0.5 * (c + c.transpose())).cholesky() {
                    Some(l) => (
                        p.error.dot(&l.solve(&p.error)),
                        l.l().diagonal().iter().map(|d| d.ln()).sum(),
                    ),
                    None => (f64::INFINITY, 0.5 * f64::MIN_POSITIVE.ln()),
                };
                Scored {
                    horizon: p.horizon,
                    saturated: p.saturated,
                    nees,
                    half_log_det,
                }
            })
            .collect())
    }

    /// Every prediction's pose covariance plus its reference's with `terms`, by the sum
    /// (replaying each term it moves off the base's once).
    pub fn covariances(&mut self, terms: Terms) -> Result<Vec<Matrix3<f64>>, CalibrationError> {
        for (i, &t) in terms.iter().enumerate() {
            if t != self.at[i] && self.per_unit[i].is_none() {
                // The base's terms with term i's variance grown by its unit's.
                let mut unit = self.at;
                unit[i] = self.at[i].hypot(UNITS[i]);
                let records = self.records(unit)?;
                if records.len() != self.predictions.len() {
                    return Err(changed());
                }
                let added = (records.iter().zip(&self.predictions))
                    .map(|(r, p)| total(r) - p.base)
                    .collect();
                self.per_unit[i] = Some(added);
            }
        }
        let weights = std::array::from_fn::<f64, TERMS, _>(|i| {
            (terms[i].powi(2) - self.at[i].powi(2)) / UNITS[i].powi(2)
        });
        Ok((self.predictions.iter().enumerate())
            .map(|(n, p)| {
                let mut c = p.base;
                for (w, added) in weights.iter().zip(&self.per_unit) {
                    if let (true, Some(added)) = (*w != 0.0, added) {
                        c += *w * added[n];
                    }
                }
                c
            })
            .collect())
    }
}

/// Every prediction of a replay's `records` (at the fit's `horizons_s`) scored as the replay
/// has it.
pub(super) fn replayed(records: &[PredictionRecord], horizons_s: &[f64]) -> Vec<Scored> {
    (records.iter())
        .map(|r| Scored {
            horizon: horizon_index(horizons_s, r),
            saturated: r.saturated_s > 0.0,
            nees: r.nees,
            half_log_det: 0.5 * total(r).determinant().max(f64::MIN_POSITIVE).ln(),
        })
        .collect()
}

fn horizon_index(horizons_s: &[f64], r: &PredictionRecord) -> usize {
    (horizons_s.iter())
        .position(|&h| h == r.horizon_s)
        .unwrap_or(0)
}

/// A record's predicted covariance plus its reference's.
fn total(r: &PredictionRecord) -> Matrix3<f64> {
    Matrix3::from(r.predicted_covariance) + Matrix3::from(r.reference_covariance)
}

fn changed() -> CalibrationError {
    CalibrationError::Scene("the replay's predictions changed with the process noise".into())
}
