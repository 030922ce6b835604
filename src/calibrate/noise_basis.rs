//! The process noise's terms scored without replaying the drives for every trial.
//!
//! The four terms (noise.rs) change the predicted covariance only: the predictions' states,
//! their integration error estimates, their saturations and the floors do not depend on them,
//! and the covariance is propagated linearly along the fixed trajectory (docs/propagation.md)
//! with the terms' variances entering additively. So a prediction's pose covariance is
//! P(σ) = P₀ + Σᵢ (σᵢ / uᵢ)² Rᵢ, where P₀ is the covariance without process noise (the start's
//! propagated, the error estimate, the floors, the reference's own) and Rᵢ what term i adds at
//! its unit value uᵢ. One replay without noise and one per term used give every trial's NEES
//! and log score by this sum; the fit's last values are replayed once more and scored directly.

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
    predictions: Vec<Prediction>,
    per_unit: [Option<Vec<Matrix3<f64>>>; TERMS],
    /// Replays of every recording it took.
    pub replays: usize,
}

impl<'a> NoiseBasis<'a> {
    /// Replays `problem`'s recordings under the scene `yaml` with every term at 0 (`write`
    /// sets the terms in a scene file).
    pub fn new(
        problem: &'a Problem<'a>,
        yaml: &Value,
        write: &'a dyn Fn(&mut Value, Terms),
        replay: EvaluationSettings,
    ) -> Result<Self, CalibrationError> {
        let mut basis = NoiseBasis {
            problem,
            yaml: yaml.clone(),
            write,
            replay,
            predictions: Vec::new(),
            per_unit: Default::default(),
            replays: 0,
        };
        let records = basis.records([0.0; TERMS])?;
        basis.predictions = (records.iter())
            .map(|r| Prediction {
                horizon: (basis.replay.horizons_s.iter())
                    .position(|&h| h == r.horizon_s)
                    .unwrap_or(0),
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
        for (i, &t) in terms.iter().enumerate() {
            if t != 0.0 && self.per_unit[i].is_none() {
                let mut unit = [0.0; TERMS];
                unit[i] = UNITS[i];
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
        let weights = std::array::from_fn::<f64, TERMS, _>(|i| (terms[i] / UNITS[i]).powi(2));
        Ok((self.predictions.iter().enumerate())
            .map(|(n, p)| {
                let mut c = p.base;
                for (w, added) in weights.iter().zip(&self.per_unit) {
                    if let (true, Some(added)) = (*w != 0.0, added) {
                        c += *w * added[n];
                    }
                }
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

    /// Every prediction scored with `terms` by a replay under them.
    pub fn replayed(&mut self, terms: Terms) -> Result<Vec<Scored>, CalibrationError> {
        let records = self.records(terms)?;
        if records.len() != self.predictions.len() {
            return Err(changed());
        }
        Ok((records.iter().zip(&self.predictions))
            .map(|(r, p)| Scored {
                horizon: p.horizon,
                saturated: p.saturated,
                nees: r.nees,
                half_log_det: 0.5 * total(r).determinant().max(f64::MIN_POSITIVE).ln(),
            })
            .collect())
    }
}

/// A record's predicted covariance plus its reference's.
fn total(r: &PredictionRecord) -> Matrix3<f64> {
    Matrix3::from(r.predicted_covariance) + Matrix3::from(r.reference_covariance)
}

fn changed() -> CalibrationError {
    CalibrationError::Scene("the replay's predictions changed with the process noise".into())
}
