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

use super::ProcessNoise;
use nalgebra::Matrix3;

/// Per prediction, in the order [`Problem::errors`](super::Problem::errors) gives them, L⁻¹ of
/// its pose covariance plus its reference's, `covariances` (the noise fit's replay under the
/// fitted values and `noise`); None when the fit keeps no process noise (the weights would be
/// the odometry's and the integration's alone) or a covariance is not positive definite.
pub(super) fn whitening(
    noise: &ProcessNoise,
    covariances: &[Matrix3<f64>],
) -> Option<Vec<Matrix3<f64>>> {
    if [
        noise.effort_noise,
        noise.saturation_slip,
        noise.saturation_turn,
        noise.slip_noise,
    ]
    .iter()
    .all(|&s| s == 0.0)
    {
        return None;
    }
    (covariances.iter())
        .map(|p| (0.5 * (p + p.transpose())).cholesky()?.l().try_inverse())
        .collect()
}
