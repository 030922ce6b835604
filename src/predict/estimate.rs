//! The global error estimate of a prediction, for every method, and what is done when it exceeds
//! `integration.max_error`.
//!
//! **Method: Richardson extrapolation against a companion run.** Beside the answer, the predictor
//! integrates a companion from the same start over the same sample and control spans, under the
//! same commands and drift control — its controllers (a copy of the actuators) close their loop
//! on its own state, as the answer's do on the answer's — with a finer setting:
//!
//! - fixed-step methods (semi-implicit Euler, RK4, SDIRK2): the step halved, two companion steps
//!   per step of the answer. With a global error `e(dt) ≈ C dt^p` (p the method's order),
//!   `e(dt) ≈ (q_dt ⊖ q_dt/2) · 2^p / (2^p − 1)`: factor 2 (SIE), 4/3 (SDIRK2), 16/15 (RK4).
//!   Cost: two extra steps per step, 3× the evaluations. ROS2's companion steps with the
//!   answer's F of the span (a W-method keeps its order with any F), so it computes no
//!   Jacobian of its own.
//! - adaptive methods (DOPRI5, DOP853, Radau5; order p): the tolerances divided by K = 2^p (32,
//!   256, 32) and every step at most half the answer's largest in the span. DOPRI5 in detail: Where the tolerance sets the step, DOPRI5's global error is about proportional
//!   to it; where the span caps the step (smooth motion, loose tolerance) both lanes would take
//!   the same single step, and the halved step divides the error by 2⁵ = 32 = K instead. Either
//!   way `e ≈ (q ⊖ q_c) · K / (K − 1)`. Cost: about K^(1/5) = 2× the steps, 3× in all.
//!
//! Why not the sum of local errors: it misses how errors grow along the motion (a pendulum's phase
//! error grows with t²), and DOPRI5's embedded estimate measures the 4th-order solution, not the
//! propagated 5th-order one (pessimistic by 1/(C h)). The companion's difference follows the
//! nonlinear dynamics, projection and constraints as they are; it is asymptotically exact and
//! measured against closed forms and far tighter runs in `tests/it/error_estimate.rs` (table in
//! docs/propagation.md). The estimate reported is the largest entry of the tangent-space
//! difference of q of each kind of coordinate, in its unit (error_kinds.rs), each checked
//! against its bound (`IntegrationSettings::error_bounds`).

use super::IntegrationSettings;
use super::drift::DriftProjector;
use super::error_kinds::{ByKind, KIND_NAMES};
use crate::error::Error;
use crate::model::Model;
use crate::predict::integrators::radau::RadauWorkspace;
use crate::predict::integrators::{ErrorEstimator, Method, StepWorkspace};
use crate::system::System;

/// An adaptive method's companion runs at rtol / K and atol / K, K = 2^p (p its order: 32 for
/// DOPRI5 and Radau5, 256 for DOP853): the error a halved step divides by.
pub(super) fn tightening(m: Method) -> f64 {
    2f64.powi(m.order() as i32)
}

/// `integration.adapt`: at most this many reruns with a refined step or tolerance.
pub(super) const MAX_REFINEMENTS: usize = 4;

/// A refinement aims at this fraction of `max_error` (the estimate is a first-order guess of how
/// the error scales).
const SAFETY: f64 = 0.5;

/// One integration of a prediction: the answer (lane 0) or its companion (lane 1), with its state,
/// step workspace and counters. Sized once per model.
#[derive(Clone, Debug, Default)]
pub(super) struct Lane {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub step: StepWorkspace,
    pub radau: RadauWorkspace,
    pub proj: DriftProjector,
    /// DOPRI5's next step [s].
    pub h: f64,
    pub steps: usize,
    pub evaluations: usize,
    pub least_squares: usize,
}

impl Lane {
    pub fn new(sys: &System) -> Self {
        let (nq, nv) = (sys.model().nq, sys.model().nv);
        Self {
            q: vec![0.0; nq],
            v: vec![0.0; nv],
            step: StepWorkspace::new(nq, nv),
            radau: RadauWorkspace::new(nq, nv),
            proj: DriftProjector::new(sys),
            h: 0.0,
            steps: 0,
            evaluations: 0,
            least_squares: 0,
        }
    }

    /// Start a run at (q, v) (q already normalised) with first step h.
    pub fn start(&mut self, q: &[f64], v: &[f64], h: f64) {
        self.q.copy_from_slice(q);
        self.v.copy_from_slice(v);
        self.step.invalidate();
        self.step.jacobians = 0;
        self.radau.reset();
        self.h = h;
        self.steps = 0;
        self.evaluations = 0;
        self.least_squares = 0;
    }
}

/// The companion's settings: half the step (fixed-step methods) or tolerances / K (DOPRI5). Its
/// step count may reach twice the answer's (fixed) or more (DOPRI5, still bounded by max_work).
pub(super) fn companion_settings(s: &IntegrationSettings) -> IntegrationSettings {
    let mut c = s.clone();
    match s.method.integrator().error_estimator() {
        ErrorEstimator::TightenedTolerances => {
            c.rtol = s.rtol / tightening(s.method);
            c.atol = s.atol / tightening(s.method);
        }
        ErrorEstimator::HalvedStep => c.dt = s.dt / 2.0,
    }
    c.max_steps = 4.0 * s.max_steps;
    c
}

/// Richardson factor turning the answer–companion difference into the answer's error.
pub(super) fn richardson_factor(method: Method) -> f64 {
    // Fixed steps: dt halved divides the error by 2^p; adaptive: tolerances / 2^p (tightening).
    let r = 2f64.powi(method.order() as i32);
    r / (r - 1.0)
}

/// The estimate by kind of coordinate: factor × the largest |(q ⊖ q_c)_i| of each kind (`diff`:
/// nv scratch).
pub(super) fn estimate(
    model: &Model,
    q: &[f64],
    q_c: &[f64],
    factor: f64,
    diff: &mut [f64],
) -> ByKind {
    model.difference(q_c, q, diff);
    ByKind::of_tangent(model, diff, factor)
}

/// The typed error of a sample whose estimate `e` at `t` exceeds a kind's bound, or None.
pub(super) fn check(s: &IntegrationSettings, e: &ByKind, t: f64, horizon: f64) -> Option<Error> {
    let bounds = s.error_bounds();
    let over = e.first_over(&bounds)?;
    Some(exceeded(s, over, e.excess(&bounds), t, horizon))
}

/// Settings expected to meet every bound over `horizon` after an estimate `excess` times its
/// bound (the largest over the kinds, [`ByKind::excess`]) at time `t`: the error is taken to grow
/// linearly in time (excess · horizon / t at the horizon) and to scale as dt^p (fixed steps) or
/// the tolerance (DOPRI5); aimed at half of the bound, and at least a 10 % refinement.
pub(super) fn refined(
    s: &IntegrationSettings,
    excess: f64,
    t: f64,
    horizon: f64,
) -> IntegrationSettings {
    let at_horizon = excess * (horizon / t.max(f64::MIN_POSITIVE)).max(1.0);
    let ratio = (SAFETY / at_horizon).min(1.0);
    let mut r = s.clone();
    match s.method {
        m if m.is_adaptive() => {
            let f = ratio.min(0.9);
            r.rtol = s.rtol * f;
            r.atol = s.atol * f;
        }
        m => r.dt = s.dt * ratio.powf(1.0 / m.order() as f64).min(0.9),
    }
    r
}

/// The typed error of a run whose estimate of `kind` at `t` exceeds its bound (`excess`: the
/// largest estimate / bound over the kinds), naming the setting that would meet every bound.
fn exceeded(
    s: &IntegrationSettings,
    (kind, estimate, max_error): (usize, f64, f64),
    excess: f64,
    t: f64,
    horizon: f64,
) -> Error {
    let r = refined(s, excess, t, horizon);
    let hint = match s.method {
        m if m.is_adaptive() => format!(
            "rtol = {:.2e}, atol = {:.2e} should meet it (the error is about proportional to the \
             tolerance), or set integration.adapt: true",
            r.rtol, r.atol
        ),
        m => format!(
            "dt = {:.3e} s should meet it ({m:?} has order {}: error ∝ dt^{}), or set \
             integration.adapt: true",
            r.dt,
            m.order(),
            m.order()
        ),
    };
    let bound = s.error_bound_key(kind);
    Error::ErrorEstimateExceeded {
        t,
        estimate,
        max_error,
        kind: KIND_NAMES[kind],
        bound,
        excess,
        hint,
    }
}
