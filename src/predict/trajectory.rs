//! What a prediction returns: samples of the state along the horizon, with what acted on the
//! robot and, on request, the constraint forces and the covariance (run/sample.rs takes them).

use super::contacts::ContactCheck;
use super::drift::OffConstraints;
use super::error_kinds::ByKind;
use crate::constraints::{ConstraintForce, ContactState};
use crate::predict::integrators::Method;

use serde::Serialize;

/// One output sample.
#[derive(Clone, Debug, Serialize)]
pub struct Sample {
    /// Time [s].
    pub t: f64,
    /// Configuration (nq).
    pub q: Vec<f64>,
    /// Velocity (nv).
    pub v: Vec<f64>,
    /// The actuators' torques held from this sample on (zero-order hold; at the last sample,
    /// those of the interval that ends there) (nv) [N·m or N]; zeros without actuators.
    pub actuator_torque: Vec<f64>,
    /// Multipliers (when forces were asked for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lambda: Option<Vec<f64>>,
    /// Each constraint's force at its frame (when forces were asked for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub forces: Option<Vec<ConstraintForce>>,
    /// Jᵀλ per velocity coordinate (nv) [N or N·m] (when forces were asked for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub generalized_force: Option<Vec<f64>>,
    /// Each contact judged at this sample's λ, in the order of `ContactCheck::contacts` (when
    /// forces were asked for and the scene has contacts): its normal force, the friction it
    /// uses and whether it breaks (predict/contacts.rs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contacts: Option<Vec<ContactState>>,
    /// nc − rank(J M⁻¹ Jᵀ) at this state (when forces were asked for): > 0 at a singular
    /// configuration or with redundant constraints, where λ is the minimum-norm solution.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rank_deficiency: Option<usize>,
    /// max |φ| over holonomic rows [m or rad].
    pub position_residual: f64,
    /// max |J v| [m/s or rad/s].
    pub velocity_residual: f64,
    /// Kinetic, and gravity + spring potential energy [J].
    pub kinetic_energy: f64,
    /// Gravity + spring potential energy [J].
    pub potential_energy: f64,
    /// Estimate of the global integration error of q at this time [m or rad]: the largest entry
    /// of the tangent-space difference from the exact solution of the integrated equations
    /// (Richardson against a companion run, `predict/estimate.rs`), every method; finite. None
    /// when `integration.error_estimate` is false.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_estimate: Option<f64>,
    /// The same estimate by kind of coordinate, each in its own unit and checked against its
    /// bound (`IntegrationSettings::error_bounds`): the base's position [m] and orientation
    /// [rad], the joints' angles [rad] and displacements [m]; `error_estimate` is their
    /// largest. None when `integration.error_estimate` is false.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_estimate_by_kind: Option<ByKind>,
    /// Propagated covariance of (δq, δv), 2nv × 2nv row-major, tangent space (δq a right
    /// perturbation, velocity order) [m², rad², (m/s)², …], when a start covariance was given
    /// (`PredictionRequest::covariance_samples`: in every sample or in the last).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Vec<Vec<f64>>>,
    /// Time a velocity controller spent saturated from the start to this sample [s]
    /// (`Trajectory::saturated_s` at the last).
    pub saturated_s: f64,
}

impl Sample {
    /// The base position's error estimate at this sample [m]: its integration error estimate
    /// (`base_m`; 0 when none was made or the base is fixed) plus the holonomic residual. The
    /// joints' angles (a wheel's is 1/r × the travel) are not in it.
    pub fn position_error_estimate(&self) -> f64 {
        self.error_estimate_by_kind.map_or(0.0, |e| e.base_m) + self.position_residual
    }

    /// The base orientation's error estimate at this sample [rad]: `base_rad` plus the
    /// holonomic residual.
    pub fn orientation_error_estimate(&self) -> f64 {
        self.error_estimate_by_kind.map_or(0.0, |e| e.base_rad) + self.position_residual
    }
}

/// A prediction.
#[derive(Clone, Debug, Serialize)]
pub struct Trajectory {
    /// Names of the configuration coordinates (order of `Sample::q`).
    pub q_names: Vec<String>,
    /// Names of the velocity coordinates (order of `Sample::v`).
    pub v_names: Vec<String>,
    /// Integration method used.
    pub method: Method,
    /// Step [s] (fixed-step methods) and relative tolerance (dopri5) of this run: the scene's,
    /// or the refined ones after `integration.adapt` reran it.
    pub dt: f64,
    /// See `dt`.
    pub rtol: f64,
    /// Reruns with a refined step or tolerance (`integration.adapt`).
    pub refinements: usize,
    /// Output samples, one every sample period over the horizon.
    pub samples: Vec<Sample>,
    /// The contacts judged at every sample (when forces were asked for): the first slip or
    /// lift-off, and the limits left unchecked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact_check: Option<ContactCheck>,
    /// How far the start state lay off the constraints (when forces were asked for): the
    /// first sample keeps the start as given, and its forces are those of its projection onto
    /// the constraints (`DriftProjector::project_measured`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_off_constraints: Option<OffConstraints>,
    /// Time the prediction spent with a velocity controller saturated (at its effort, or a diff
    /// drive's traction torque) [s]: where the robot cannot follow its command, and where the
    /// model knows least what the floor takes (`uncertainty.saturation_bias`).
    pub saturated_s: f64,
    /// Accepted steps and right-hand-side evaluations.
    pub steps: usize,
    /// Right-hand-side (forward dynamics) evaluations.
    pub evaluations: usize,
    /// Evaluations where the constraint accelerations were inconsistent (at or next to a singular
    /// configuration) and were met in the least-squares sense instead.
    pub least_squares_evaluations: usize,
    /// Jacobians of the implicit Newton iteration (radau5; analytic where the scene has
    /// derivatives, else by 2nv evaluations counted in `evaluations`).
    pub jacobians: usize,
    /// Evaluations of the error estimate's companion run (not in `evaluations`).
    pub estimate_evaluations: usize,
    /// Linearized steps of the covariance propagation, tried ones included (0 without a
    /// start covariance): one per step where a stiff mode keeps the chunks to a single step
    /// (covariance/chunks.rs).
    pub covariance_linearizations: usize,
    /// Wall time spent propagating the covariance [s], part of `run_time_s`.
    pub covariance_time_s: f64,
    /// The covariance was propagated on a second thread beside the prediction
    /// (`Predictor::with_parallel_covariance`): `covariance_time_s` then overlaps the prediction's
    /// own time instead of adding to it.
    pub covariance_on_worker: bool,
    /// CPU (wall) time of the integration [s].
    pub run_time_s: f64,
}

impl Trajectory {
    /// The first sample and contact where ideal rolling breaks (with forces; None without, or
    /// when every contact holds).
    pub fn first_contact_break(&self) -> Option<&super::contacts::ContactBreak> {
        self.contact_check.as_ref()?.first_break.as_ref()
    }
}
