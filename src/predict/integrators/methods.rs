//! The methods: the [`Method`] a scene names, mapped once (`methods!`) to its implementation,
//! which says what the prediction needs to know of it ([`Integrator`]) and steps
//! ([`Step`]).

use super::radau::{self, RadauWorkspace};
use super::{Accel, StepWorkspace, explicit, ros2, sdirk2};
use crate::error::{Error, Result};
use crate::model::Model;
use crate::predict::IntegrationSettings;
use crate::predict::covariance::linearize::Linearization;
use crate::system::System;
use serde::{Deserialize, Serialize};

/// The enum of the methods and its one map to their implementations, from one list of entries
/// `doc, Variant = "name" => implementation`.
macro_rules! methods {
    ($($(#[$attr:meta])* $variant:ident = $name:literal => $imp:path,)*) => {
        /// The integration method a scene or request chooses.
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
        pub enum Method {
            $($(#[$attr])* #[serde(rename = $name)] $variant,)*
        }

        impl Method {
            /// Every method.
            pub const ALL: &'static [Method] = &[$(Method::$variant),*];

            /// The name a scene or the CLI uses.
            pub fn name(self) -> &'static str {
                match self {
                    $(Method::$variant => $name,)*
                }
            }

            /// What the rest of the prediction needs to know of this method.
            pub fn integrator(self) -> &'static dyn Integrator {
                match self {
                    $(Method::$variant => &$imp,)*
                }
            }

            /// One step of this method ([`Step::step`]), each method's monomorphic.
            #[allow(clippy::too_many_arguments)]
            #[inline]
            pub(in crate::predict) fn step<F: Accel>(
                self,
                f: &mut F,
                model: &Model,
                span: (f64, f64),
                q: &mut [f64],
                v: &mut [f64],
                ws: &mut StepWorkspace,
                radau: &mut RadauWorkspace,
                s: &IntegrationSettings,
            ) -> Result<Option<StepOutcome>> {
                match self {
                    $(Method::$variant => $imp.step(f, model, span, q, v, ws, radau, s),)*
                }
            }

            /// One step of this method with its linearization ([`Step::linearize`]).
            pub(in crate::predict) fn linearize(
                self,
                sys: &mut System,
                lin: &mut Linearization,
                x: (&[f64], &[f64]),
                tau: &[f64],
                dt: f64,
            ) -> Result<()> {
                match self {
                    $(Method::$variant => $imp.linearize(sys, lin, x, tau, dt),)*
                }
            }
        }
    };
}

// One entry per method: the enum, its names, the CLI's help and the dispatch of steps and
// linearizations follow from it.
methods! {
    /// Semi-implicit (symplectic) Euler: v⁺ = v + dt q̈(q, v), q⁺ = q ⊕ dt v⁺. Order 1.
    SemiImplicitEuler = "semi_implicit_euler" => explicit::SemiImplicitEuler,
    /// Classical Runge–Kutta, order 4 (Munthe-Kaas on the group).
    #[default]
    Rk4 = "rk4" => explicit::Rk4,
    /// Dormand–Prince 5(4), adaptive with rtol/atol and an error estimate.
    Dopri5 = "dopri5" => explicit::Dopri5,
    /// Dormand–Prince 8(5,3), adaptive with rtol/atol: tight tolerances on smooth scenes in
    /// fewer evaluations than DOPRI5.
    Dop853 = "dop853" => explicit::Dop853,
    /// Alexander's 2-stage L-stable SDIRK (order 2) with simplified Newton: for stiff scenes.
    Sdirk2 = "sdirk2" => sdirk2::Sdirk2,
    /// Radau IIA of order 5 (3 implicit stages, L-stable), adaptive with rtol/atol (radau.rs):
    /// for stiff scenes at any accuracy.
    Radau5 = "radau5" => radau::Radau5,
    /// ROS2, a two-stage linearly implicit W-method of order 2, L-stable (ros2.rs): stiff
    /// controlled scenes at planning accuracy, two evaluations and one Jacobian a step.
    Ros2 = "ros2" => ros2::Ros2,
}

impl Method {
    /// Order of the global error (error ∝ dt^p for fixed steps); an embedded pair's is that of
    /// its propagated solution.
    pub fn order(self) -> u32 {
        self.integrator().order()
    }

    /// The step adapts to rtol/atol (`dt` is only the first step).
    pub fn is_adaptive(self) -> bool {
        self.integrator().is_adaptive()
    }

    /// Explicit methods' stability limit of dt·|λ| on the imaginary axis (oscillators).
    pub fn explicit_stability_limit(self) -> Option<f64> {
        self.integrator().stability_limit()
    }

    /// The names of `methods` joined by `separator` (the CLI's help and its parse errors).
    pub fn names(methods: impl IntoIterator<Item = Method>, separator: &str) -> String {
        let names: Vec<&str> = methods.into_iter().map(Method::name).collect();
        names.join(separator)
    }

    /// The methods whose step [`linearize_step`](crate::predict::linearize_step) linearizes.
    pub fn linearizable() -> impl Iterator<Item = Method> {
        (Method::ALL.iter().copied()).filter(|m| m.integrator().linearized_as().is_some())
    }
}

/// How the error estimate's companion run is made finer than the answer (estimate.rs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ErrorEstimator {
    /// Two companion steps of dt/2 per step: the error divides by 2^p.
    HalvedStep,
    /// The companion's rtol and atol divided by 2^p (the adaptive methods).
    TightenedTolerances,
}

/// What the prediction loop, its work bound, its error estimate and its covariance know of an
/// integration method; its step is its [`Step`].
pub trait Integrator: Sync {
    /// The method a scene names.
    fn method(&self) -> Method;
    /// Order p of the global error (∝ dt^p).
    fn order(&self) -> u32;
    /// Right-hand-side evaluations per step of a fixed-step method, counted before running;
    /// None where the step adapts or iterates (counted while running).
    fn evaluations_per_step(&self) -> Option<f64>;
    /// The step adapts to rtol/atol (`dt` is only the first step).
    fn is_adaptive(&self) -> bool;
    /// The stages are implicit (a Newton iteration on the step's Jacobian).
    fn is_implicit(&self) -> bool;
    /// The stability region's extent along the imaginary axis, dt·|λ| (undamped oscillators), for
    /// the explicit methods; None for the L-stable implicit ones.
    fn stability_limit(&self) -> Option<f64>;
    /// How the error estimate's companion is refined.
    fn error_estimator(&self) -> ErrorEstimator {
        match self.is_adaptive() {
            true => ErrorEstimator::TightenedTolerances,
            false => ErrorEstimator::HalvedStep,
        }
    }
    /// The method whose step the covariance linearizes over chunks of this method's steps
    /// (covariance/chunks.rs); None where the step's sensitivity is not implemented.
    fn linearized_as(&self) -> Option<Method>;
    /// Where the step's own sensitivity is not implemented (`linearized_as` None): the
    /// covariance covers each step with ROS2 steps of the variational equation, L-stable, in as
    /// many substeps as settle Φ (covariance/substeps.rs). False: the covariance is refused.
    fn covariance_by_substeps(&self) -> bool {
        false
    }
    /// A W-method (ROS2): its order holds with any F, so the prediction decides when F is
    /// refreshed, re-formed for the controllers or shared with the error estimate's companion
    /// (run/mod.rs), and the covariance linearizes each step with the F and increment it took.
    fn is_w_method(&self) -> bool {
        false
    }
}

/// What an adaptive step did: accepted (the state advanced) or rejected (the state is
/// unchanged), and the step to try next [s].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOutcome {
    pub accepted: bool,
    pub h_next: f64,
}

/// The step of a method, companion of [`Integrator`]: generic over the right-hand side so that
/// a dynamics evaluation is inlined into the stages (not object safe: dispatched by
/// [`Method::step`]).
pub(in crate::predict) trait Step: Integrator {
    /// One step of `dt` from (q, v) at t in place (`span` = (t, dt)), with the shared buffers
    /// `ws` and Radau IIA's `radau`; an adaptive method's outcome (a rejected step leaves (q, v)
    /// as they were), None for a fixed step.
    #[allow(clippy::too_many_arguments)]
    fn step<F: Accel>(
        &self,
        f: &mut F,
        model: &Model,
        span: (f64, f64),
        q: &mut [f64],
        v: &mut [f64],
        ws: &mut StepWorkspace,
        radau: &mut RadauWorkspace,
        s: &IntegrationSettings,
    ) -> Result<Option<StepOutcome>>;

    /// The step from x = (q, v) under the held τ with its sensitivity into `lin`
    /// (covariance/linearize.rs). Default: refused, where `linearized_as` is None.
    fn linearize(
        &self,
        _sys: &mut System,
        _lin: &mut Linearization,
        _x: (&[f64], &[f64]),
        _tau: &[f64],
        _dt: f64,
    ) -> Result<()> {
        let methods = Method::names(Method::linearizable(), ", ");
        Err(Error::Unsupported {
            what: format!("linearize with {:?}", self.method()),
            why: format!(
                "the implicit step's sensitivity is not implemented; use one of {methods}"
            ),
        })
    }
}
