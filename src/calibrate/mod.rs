//! Calibration: the values of a scene that make its predictions match recorded drives
//! (docs/logs.md). ROS-free: a log reader fills the [`Recording`]s.
//!
//! - `parameters.rs`: what can be fitted and where it goes in the scene file;
//! - `problem.rs`: the residuals, the replayed predictions' errors at trial values (the last
//!   few kept: a weighted round starts where the last fit ended), and where the fit starts;
//! - `least_squares.rs`: Levenberg–Marquardt on the replayed predictions' errors, and the
//!   fitted values' covariance (standard errors and correlations, the overlapping
//!   predictions' shared errors counted);
//! - `noise.rs`: the process noise that makes the predicted covariance cover what the model
//!   still misses;
//! - `noise_basis.rs`: the noise's trials scored from one replay per term they move, the
//!   covariance being linear in the terms' variances;
//! - `weighting.rs`: once the noise is known, the fit again with each prediction's error
//!   weighed by its own predicted covariance, and the noise sized again.
//!
//! The replay is [`crate::replay::evaluate`]'s: the same starts, commands and predictions the
//! `evaluate` command scores.

mod least_squares;
mod noise;
mod noise_basis;
mod parameters;
mod problem;
mod weighting;

pub use noise::ProcessNoise;
pub use parameters::{FitParameter, SceneParameters};

pub(crate) use problem::Problem;
use problem::start;

use crate::replay::{EvaluationSettings, Recording, ReplayError};
use crate::scene::{Scene, SceneFile};
use nalgebra::DVector;
use serde::Serialize;
use serde_yaml::Value;
use std::path::Path;

/// Rounds of the fit weighed by the predictions' covariances at most (weighting.rs): on the
/// bundled drive the values move by up to 0.7 of their standard errors in the second round and
/// by under 0.3 in the third.
const WEIGHTED_ROUNDS: usize = 3;
/// The weighted rounds stop when no value moves by more than this many standard errors.
const SETTLED: f64 = 0.5;

/// What a calibration fits and how.
#[derive(Clone, Debug)]
pub struct CalibrationSettings {
    /// The parameters to fit; empty: every one the scene can take
    /// ([`SceneParameters::unavailable`]).
    pub fit: Vec<FitParameter>,
    /// The replay: horizons, start period, the node's covariance settings.
    pub replay: EvaluationSettings,
    /// Also fit the process noise (`uncertainty:`: the wheels' effort noise, the skid's slide
    /// and turn on the base, the base yaw's slip noise; noise.rs).
    pub fit_process_noise: bool,
    /// The coverage of the 95 % region the wheels' effort noise and the skid's terms are sized
    /// to (the slip noise is the most likely value beside them).
    pub target_coverage_p95: f64,
    /// Levenberg–Marquardt's budget: at most this many times (parameters + 1) replays.
    pub max_iterations: usize,
}

impl Default for CalibrationSettings {
    fn default() -> Self {
        CalibrationSettings {
            fit: Vec::new(),
            replay: EvaluationSettings {
                horizons_s: vec![0.5, 1.0, 2.0],
                ..EvaluationSettings::default()
            },
            fit_process_noise: true,
            target_coverage_p95: 0.95,
            max_iterations: 30,
        }
    }
}

/// One fitted value.
#[derive(Clone, Debug, Serialize)]
pub struct FittedParameter {
    /// Its name ([`FitParameter::name`]).
    pub name: &'static str,
    /// Its unit.
    pub unit: &'static str,
    /// The scene's value.
    pub scene_value: f64,
    /// The calibrated value (the scene's when not fitted).
    pub value: f64,
    /// Its standard error, with the overlapping predictions' shared errors counted
    /// (least_squares.rs; absent where the recordings do not move the predictions at all
    /// along it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub std_error: Option<f64>,
    /// Whether it was fitted: its change from the scene's value is at least twice its
    /// standard error. Otherwise it stays at the scene's value.
    pub fitted: bool,
    /// Whether the recordings determine it: fitted, or its standard error below the size a
    /// change must reach to matter (the fit's scale, [`SceneParameters::scale`]: the recordings
    /// then confirm the scene's value). Neither where no standard error is known.
    pub determined: bool,
}

/// The correlation of two fitted values' estimates (from the covariance whose diagonal gives
/// their standard errors).
#[derive(Clone, Debug, Serialize)]
pub struct Correlation {
    /// The two parameters' names.
    pub between: [&'static str; 2],
    /// In [−1, 1].
    pub value: f64,
}

/// A calibration's result.
#[derive(Clone, Debug, Serialize)]
pub struct Calibration {
    /// The fitted values, in [`FitParameter::ALL`]'s order.
    pub parameters: Vec<FittedParameter>,
    /// The correlations of the fitted values' estimates, every pair: near ±1, the drives
    /// tell the two apart poorly and a change of one is largely taken up by the other.
    pub correlations: Vec<Correlation>,
    /// The fitted process noise (absent when not asked for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub process_noise: Option<ProcessNoise>,
    /// RMS of the normalised residuals at the scene's values and at the calibrated ones
    /// (1 = as large as the scene's errors).
    pub residual_rms: [f64; 2],
    /// Replays of every recording the fit took.
    pub replays: usize,
    /// How Levenberg–Marquardt ended.
    pub termination: String,
    /// The calibrated scene file (the input's YAML with the fitted values written in).
    #[serde(skip)]
    pub scene: Value,
}

/// Why a calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// A parameter cannot be fitted on this scene.
    #[error("--fit {name}: {why}")]
    Unavailable {
        /// The parameter.
        name: &'static str,
        /// Why.
        why: String,
    },
    /// The scene file's YAML does not build a scene.
    #[error("{0}")]
    Scene(String),
    /// A recording cannot be replayed at the scene's own values.
    #[error(transparent)]
    Replay(#[from] ReplayError),
}

/// The scene to calibrate: its file's YAML, where it came from, and its URDF.
pub struct SceneSource<'a> {
    /// The scene file's YAML.
    pub yaml: &'a Value,
    /// The scene file's path (for errors).
    pub path: &'a Path,
    /// The URDF's text and name.
    pub urdf: (&'a str, &'a str),
}

impl SceneSource<'_> {
    /// The scene of `yaml` (this source's file with values written in).
    pub fn build(&self, yaml: &Value) -> Result<Scene, CalibrationError> {
        let file: SceneFile = serde_yaml::from_value(yaml.clone())
            .map_err(|e| CalibrationError::Scene(format!("{}: {e}", self.path.display())))?;
        Scene::from_parts(self.path, file, self.urdf.0, self.urdf.1)
            .map_err(|e| CalibrationError::Scene(e.to_string()))
    }
}

/// Calibrates `source` on `recordings` (module documentation).
pub fn calibrate(
    source: &SceneSource,
    recordings: &[Recording],
    settings: &CalibrationSettings,
) -> Result<Calibration, CalibrationError> {
    let scene = source.build(source.yaml)?;
    let places =
        SceneParameters::new(source.yaml, &scene.model).map_err(CalibrationError::Scene)?;
    let asked: Vec<FitParameter> = if settings.fit.is_empty() {
        places.available()
    } else {
        let mut asked = settings.fit.clone();
        asked.sort();
        asked.dedup();
        for p in &asked {
            if let Some(why) = places.unavailable(*p) {
                return Err(CalibrationError::Unavailable {
                    name: p.name(),
                    why,
                });
            }
        }
        asked
    };
    // The residuals are the errors alone (the weights are fixed between replays): no
    // covariance and no error estimate, which would cost more than the predictions.
    let replay = EvaluationSettings {
        propagate_covariance: false,
        error_estimate: false,
        ..settings.replay.clone()
    };
    let mut problem = Problem {
        source,
        places,
        recordings,
        replay,
        fitted: Vec::new(),
        norms: vec![[1.0, 1.0]; settings.replay.horizons_s.len()],
        whitening: None,
        starts: Vec::new(),
        count: 0,
        replayed: Default::default(),
        replays: Default::default(),
    };
    // The normalisation: each kind's RMS per horizon at the scene's values.
    let (starts, base): (Vec<_>, Vec<_>) = problem.errors_by_start(&[])?.into_iter().unzip();
    problem.count = 3 * base.len();
    problem.starts = starts.iter().flat_map(|s| [*s; 3]).collect();
    let mut sums = vec![[0.0, 0.0, 0.0]; problem.norms.len()];
    for (k, e) in &base {
        sums[*k][0] += e[0] * e[0] + e[1] * e[1];
        sums[*k][1] += e[2] * e[2];
        sums[*k][2] += 1.0;
    }
    for (n, s) in problem.norms.iter_mut().zip(&sums) {
        let c = s[2].max(1.0);
        *n = [
            (s[0] / (2.0 * c)).sqrt().max(1e-4),
            (s[1] / c).sqrt().max(1e-4),
        ];
    }
    let rms = |r: &DVector<f64>| (r.norm_squared() / r.len().max(1) as f64).sqrt();
    let before = rms(&problem.residuals(&[])?);

    let mut values = fit_values(&mut problem, &scene.model, asked.clone(), None, settings)?;
    // The noise's replays; the fit's are counted by the problem.
    let mut replays = 0;
    let mut yaml = problem.yaml_at(values.x.as_slice());
    let mut process_noise = None;
    if settings.fit_process_noise {
        let (mut noise, mut covariances) = noise::fit(&problem, &mut yaml, settings, None)?;
        replays += noise.replays;
        // With the process noise known, the predictions' own covariances weigh their errors
        // (weighting.rs): fit again from the values found, size the noise again, and repeat
        // with the new covariances until the values settle.
        // Nothing left to weigh where every value went back to the scene's.
        for _ in 0..if problem.fitted.is_empty() {
            0
        } else {
            WEIGHTED_ROUNDS
        } {
            let Some(whitening) =
                weighting::whitening(&noise, &covariances).filter(|w| 3 * w.len() == problem.count)
            else {
                break;
            };
            problem.whitening = Some(whitening);
            let from: Vec<(FitParameter, f64)> = (problem.fitted.iter().zip(values.x.iter()))
                .map(|(f, x)| (f.0, *x))
                .collect();
            let kept = from.iter().map(|f| f.0).collect();
            let mut weighted = fit_values(&mut problem, &scene.model, kept, Some(&from), settings)?;
            weighted.dropped.extend(values.dropped);
            let settled = (problem.fitted.iter().zip(weighted.x.iter()))
                .zip(&weighted.std_errors)
                .all(|((f, x), se)| {
                    let before = from.iter().find(|b| b.0 == f.0).map_or(0.0, |b| b.1);
                    se.is_some_and(|se| (x - before).abs() <= SETTLED * se)
                });
            values = weighted;
            problem.whitening = None;
            yaml = problem.yaml_at(values.x.as_slice());
            let kept = [noise.saturation_slip, noise.saturation_turn];
            (noise, covariances) = noise::fit(&problem, &mut yaml, settings, Some(kept))?;
            replays += noise.replays;
            if settled {
                break;
            }
        }
        // What is reported is scored by a replay under the values found, not by the sum.
        noise::rescore(&problem, &yaml, settings, &mut noise)?;
        replays += 1;
        process_noise = Some(noise);
    }
    let after = rms(&problem.residuals(values.x.as_slice())?);
    let mut parameters = Vec::new();
    for p in asked {
        let scene_value = problem.places.value(source.yaml, p);
        let scale = problem.places.scale(p, &scene.model);
        let k = problem.fitted.iter().position(|f| f.0 == p);
        let std_error = match k {
            Some(k) => values.std_errors[k].map(|s| s * scale),
            None => (values.dropped.iter()).find(|d| d.0 == p).and_then(|d| d.1),
        };
        parameters.push(FittedParameter {
            name: p.name(),
            unit: p.unit(),
            scene_value,
            value: k.map_or(scene_value, |k| scene_value + scale * values.x[k]),
            std_error,
            fitted: k.is_some(),
            determined: k.is_some() || std_error.is_some_and(|s| s < scale),
        });
    }
    let correlations = (values.correlations.iter())
        .map(|&(a, b, value)| Correlation {
            between: [problem.fitted[a].0.name(), problem.fitted[b].0.name()],
            value,
        })
        .collect();
    Ok(Calibration {
        parameters,
        correlations,
        process_noise,
        residual_rms: [before, after],
        replays: replays + problem.replays.get(),
        termination: values.termination,
        scene: yaml,
    })
}

/// What [`fit_values`] found.
struct Values {
    /// The scaled offsets of `problem.fitted` from the scene's values.
    x: DVector<f64>,
    /// How Levenberg–Marquardt ended.
    termination: String,
    /// Their standard errors, scaled.
    std_errors: Vec<Option<f64>>,
    /// The correlations of their estimates: (index, index, correlation).
    correlations: Vec<(usize, usize, f64)>,
    /// The parameters sent back to the scene's value, with their standard error [their unit].
    dropped: Vec<(FitParameter, Option<f64>)>,
}

/// Fits `fitted` from `from` (their scaled offsets; else from [`start`]); while the
/// recordings leave a parameter undetermined, the least determined one goes back to the scene's
/// value and the others are fitted again without it. Leaves `problem.fitted` at the parameters
/// kept.
fn fit_values(
    problem: &mut Problem,
    model: &crate::Model,
    mut fitted: Vec<FitParameter>,
    from: Option<&[(FitParameter, f64)]>,
    settings: &CalibrationSettings,
) -> Result<Values, CalibrationError> {
    let mut dropped: Vec<(FitParameter, Option<f64>)> = Vec::new();
    loop {
        problem.fitted = fitted
            .iter()
            .map(|&p| {
                let value = problem.places.value(problem.source.yaml, p);
                (p, value, problem.places.scale(p, model))
            })
            .collect();
        if fitted.is_empty() {
            return Ok(Values {
                x: DVector::zeros(0),
                termination: "nothing to fit".to_string(),
                std_errors: Vec::new(),
                correlations: Vec::new(),
                dropped,
            });
        }
        let x0 = match from {
            Some(from) => DVector::from_iterator(
                fitted.len(),
                (fitted.iter()).map(|p| from.iter().find(|f| f.0 == *p).map_or(0.0, |f| f.1)),
            ),
            None => start(problem)?,
        };
        let (x, termination) = least_squares::minimize(problem, x0, settings.max_iterations);
        let fit = least_squares::Fit {
            problem,
            x: x.clone(),
        };
        let (Some(j), Some(r)) = (fit.jacobian_at(&x), fit.residuals_at(&x)) else {
            return Err(CalibrationError::Scene(
                "the replay fails at the fitted values".into(),
            ));
        };
        let spread = least_squares::spread(&j, &r, &problem.starts, problem.lags());
        let std_errors = spread.std_errors();
        // The weakest parameter goes back to the scene's value alone, and the others are
        // fitted again: parameters that trade against each other (a mass against a traction
        // torque) are each poorly determined while together they are not, and dropping every
        // weak one at once would drop the pair.
        let significance = |k: usize| {
            std_errors[k].map_or(0.0, |s| {
                if s > 0.0 {
                    x[k].abs() / s
                } else {
                    f64::INFINITY
                }
            })
        };
        let weakest = (0..fitted.len())
            .min_by(|&a, &b| significance(a).total_cmp(&significance(b)))
            .filter(|&k| significance(k) < 2.0);
        let keep: Vec<bool> = (0..fitted.len()).map(|k| Some(k) != weakest).collect();
        if keep.iter().all(|&k| k) {
            let n = fitted.len();
            let correlations = (0..n)
                .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
                .filter_map(|(a, b)| spread.correlation(a, b).map(|c| (a, b, c)))
                .collect();
            return Ok(Values {
                x,
                termination,
                std_errors,
                correlations,
                dropped,
            });
        }
        for (k, f) in problem.fitted.iter().enumerate() {
            if !keep[k] {
                dropped.push((f.0, std_errors[k].map(|s| s * f.2)));
            }
        }
        fitted = (fitted.iter().zip(&keep))
            .filter(|(_, k)| **k)
            .map(|(p, _)| *p)
            .collect();
        if fitted.is_empty() {
            problem.fitted.clear();
            return Ok(Values {
                x: DVector::zeros(0),
                termination,
                std_errors: Vec::new(),
                correlations: Vec::new(),
                dropped,
            });
        }
    }
}
