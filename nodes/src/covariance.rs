//! Odometry covariances in ROS messages: the check of what arrives. The conversions between
//! their REP-103 layout and the core's tangent space are the core's
//! (`constraint_dynamics::model::base_covariance`), re-exported here.

use constraint_dynamics::BaseType;
pub use constraint_dynamics::model::base_covariance::{
    AgeNoise, JointSigma, odometry_covariance, rep103_indices, start_covariance,
};

#[cfg(test)]
use constraint_dynamics::Model;
#[cfg(test)]
use constraint_dynamics::model::base_covariance::{covariance_block as block, world_to_body};

use crate::error::NodeError;

/// Checks the entries of an odometry covariance the base uses: finite, diagonal ≥ 0.
pub fn check_odometry_covariance(
    base: BaseType,
    what: &str,
    c: &[f64; 36],
) -> Result<(), NodeError> {
    let idx = rep103_indices(base);
    for &i in idx {
        for &j in idx {
            let x = c[6 * i + j];
            if !x.is_finite() || (i == j && x < 0.0) {
                return Err(NodeError::message(
                    format!("Odometry: {what}.covariance[{}]", 6 * i + j),
                    format!("is {x} (must be finite, and ≥ 0 on the diagonal)"),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
#[path = "covariance_tests.rs"]
mod tests;
