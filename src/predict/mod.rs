//! Prediction: a scene's predictor, asked a [`PredictionRequest`] — start state, horizon, commands
//! over time, what to record — returns a [`Trajectory`]: samples of q, v, the actuator torques,
//! λ and the constraint forces when asked, constraint residuals (position and velocity),
//! energies, a global error estimate of q (estimate.rs: Richardson against a companion run,
//! every method; by kind of coordinate in error_kinds.rs) and, from a start covariance, the propagated covariance (covariance/).
//!
//! - [`Predictor`] (predictor.rs): an immutable configuration built from the scene (model,
//!   constraints, force elements, controllers, `integration:`, `uncertainty:`) and the
//!   workspace its runs reuse; [`Predictor::predict`] is the one entry point,
//!   [`Predictor::rollouts`] runs N command sequences from one state over the cores.
//! - request.rs: the request, its per-call integration overrides, and [`PredictionBudget`], the
//!   one place a request's horizon and work are resolved and bounded.
//! - run.rs and advance.rs: the loop over control ticks and samples, and the integration spans
//!   between them with drift control ([`drift`]) after every step.
//! - integrators/: the methods on the configuration Lie group, one file per family, each
//!   described by the [`Integrator`] trait.
//! - covariance/: the covariance carried through the integrator's own step linearization.

mod contacts;
mod covariance;
pub mod drift;
pub mod error_kinds;
mod estimate;
mod integrators;
mod invariant;
mod predictor;
mod request;
mod rollout;
mod run;
mod settings;
mod trajectory;

pub use contacts::{ContactBreak, ContactCheck, ContactJudge};
pub use covariance::linearize::{Linearization, linearize_step};
pub(crate) use covariance::noise_variances;
pub use covariance::{CovariancePropagator, UncertaintySpec};
pub use drift::{DriftProjector, OffConstraints};
pub use integrators::{ErrorEstimator, Integrator, Method};
pub use invariant::InvariantDynamics;
pub use predictor::{Predictor, PredictorConfig};
pub use request::{
    CovarianceSamples, IntegrationOverrides, PredictionBudget, PredictionRequest, PredictionWork,
};
pub use rollout::RolloutOptions;
pub use settings::{DriftControl, IntegrationSettings};
pub use trajectory::{Sample, Trajectory};
