//! The fit's weights once the process noise is known: each prediction's error whitened by its
//! own predicted pose covariance.
//!
//! Before the noise is known every prediction at a horizon weighs alike. That lets the
//! predictions the model knows least — through a skid, where the fitted skid's slide and turn
//! widen their covariance many times — pull the deterministic values as hard as the rest, and
//! the fit leans towards the skids (a shorter radius, a wider track) at the smooth driving's
//! cost. With the covariance P = L Lᵀ the node would publish (propagated with the fitted noise,
//! plus the reference's own), the residual L⁻¹ e makes the sum of squares the sum of the
//! predictions' NEES: generalized least squares, the weights held through a fit and taken again
//! from the new values and noise between fits until the values settle (`WEIGHTED_ROUNDS`).

use super::{CalibrationError, Problem, ProcessNoise};
use crate::replay::{EvaluationSettings, evaluate};
use nalgebra::Matrix3;
use serde_yaml::Value;

/// Per prediction, in the order [`Problem::errors`] gives them, L⁻¹ of its pose covariance
/// under the scene `yaml` (fitted values and `noise` written in); None when the fit keeps no
/// process noise (the weights would be the odometry's and the integration's alone) or a
/// covariance is not positive definite.
pub(super) fn whitening(
    problem: &Problem,
    yaml: &Value,
    noise: &ProcessNoise,
) -> Result<Option<Vec<Matrix3<f64>>>, CalibrationError> {
    if [
        noise.effort_noise,
        noise.saturation_slip,
        noise.saturation_turn,
        noise.slip_noise,
    ]
    .iter()
    .all(|&s| s == 0.0)
    {
        return Ok(None);
    }
    let replay = EvaluationSettings {
        propagate_covariance: true,
        error_estimate: true,
        ..problem.replay.clone()
    };
    let scene = problem.source.build(yaml)?;
    let mut out = Vec::new();
    for recording in problem.recordings {
        let ev = evaluate(&scene, recording, &replay)?;
        for r in &ev.records {
            let p = Matrix3::from(r.predicted_covariance) + Matrix3::from(r.reference_covariance);
            let Some(l) = (0.5 * (p + p.transpose())).cholesky() else {
                return Ok(None);
            };
            let Some(inv) = l.l().try_inverse() else {
                return Ok(None);
            };
            out.push(inv);
        }
    }
    Ok((3 * out.len() == problem.count).then_some(out))
}
