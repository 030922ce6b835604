//! The documented ranges of inputs and the work a request may ask for. Every bound here is far
//! beyond any robot and well inside f64: past them products overflow (a 1e308 m wheel radius
//! squared is infinite) or a request never ends (`dt = 1e-300`), so they are refused where the
//! input is named instead. `README.md` ("Robots and limits") lists them.

use crate::error::{Error, Result};

/// |g| [m/s²] (a thousand times Earth's).
pub const MAX_GRAVITY: f64 = 1e4;
/// Lengths in a scene: points, distances, wheel radii [m].
pub const MAX_LENGTH: f64 = 1e6;
/// Dimensionless scene coefficients (coupling a, b, c; ratios) in magnitude.
pub const MAX_COEFFICIENT: f64 = 1e9;
/// Baumgarte time constant range [s]: K_p = 1/T² must stay a number (T = 1e-300 gave ∞).
pub const BAUMGARTE_TIME_CONSTANT: (f64, f64) = (1e-6, 1e6);
/// Explicit Baumgarte gains: K_p [1/s²] and K_d [1/s] at most (T = 1e-6 s).
pub const MAX_BAUMGARTE_GAINS: (f64, f64) = (1e12, 2e6);
/// A state given as input: |q| [m or rad], |v| [m/s or rad/s] and |τ| [N or N·m] at most.
pub const MAX_STATE: (f64, f64, f64) = (1e9, 1e6, 1e12);
/// Default `integration.max_steps`: integration steps (or control ticks) per prediction.
pub const DEFAULT_MAX_STEPS: f64 = 1e6;
/// Default `integration.max_samples`: output samples per prediction.
pub const DEFAULT_MAX_SAMPLES: f64 = 1e5;
/// Default `integration.max_work`: dynamics evaluations × the system's cost per evaluation
/// ([`EvaluationCost`]), ≈ 10–60 s of CPU.
pub const DEFAULT_MAX_WORK: f64 = 1e10;

/// `x` finite and within [lo, hi], or an error naming `what` and the range.
pub fn check_range(what: &str, x: f64, lo: f64, hi: f64, unit: &str) -> Result<()> {
    if x.is_finite() && x >= lo && x <= hi {
        return Ok(());
    }
    Err(Error::Invalid(format!(
        "{what} = {x:e} {unit} is outside the accepted range [{lo:e}, {hi:e}] {unit}"
    )))
}

/// Every entry of `x` finite with |x_i| ≤ `max`, naming `what` and the entry.
pub fn check_magnitude(what: &str, x: &[f64], max: f64, unit: &str) -> Result<()> {
    crate::error::check_finite(what, x)?;
    match x.iter().position(|v| v.abs() > max) {
        Some(i) => Err(Error::Invalid(format!(
            "{what}: entry {i} = {:e} {unit} is beyond the accepted magnitude {max:e} {unit}",
            x[i]
        ))),
        None => Ok(()),
    }
}

/// A state given as input (a state file, a request, a prediction's start): sizes, finiteness
/// and the `MAX_STATE` magnitudes.
pub fn check_input_state(model: &crate::Model, q: &[f64], v: &[f64], tau: &[f64]) -> Result<()> {
    model.check_state(q, v)?;
    crate::error::check_len("tau", tau, model.nv)?;
    check_magnitude("q", q, MAX_STATE.0, "m or rad")?;
    check_magnitude("v", v, MAX_STATE.1, "m/s or rad/s")?;
    check_magnitude("tau", tau, MAX_STATE.2, "N or N·m")
}

/// Work units of one body in ABA's pass (the linear-time path): the dense path's units per
/// coordinate on the chain where both take the same time — mean depth
/// `LINEAR_MIN_MEAN_DEPTH` = 15, n = 29: (29 + Σ k²) / 29 = 296.
pub const LINEAR_UNITS_PER_BODY: f64 = 300.0;

/// Work units of one body in a constraint row's pass on the linear-time path (its innovations,
/// a force pass without ABA's inertias): a tenth of ABA's. Measured on the 1 000-link chain
/// (benches/chain.rs): three rows, their Gram matrix and solve add 46 µs to ABA's 503 µs,
/// 15 ns a body a row against ABA's 500.
pub const LINEAR_UNITS_PER_BODY_ROW: f64 = 30.0;

/// The cost of one dynamics evaluation of a system in work units, on the path it takes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EvaluationCost {
    /// The dense path's: bodies + Σ over velocity coordinates of (depth in the tree)², the
    /// operation count of M's sparse factorization. The implicit methods pay it on every path:
    /// their F (the dynamics' derivatives, nv × 2nv) and its factor are dense.
    pub dense: f64,
    /// The linear-time path's, where the system's dynamics take it
    /// ([`crate::dynamics::takes_linear_path`]): bodies × [`LINEAR_UNITS_PER_BODY`] + per
    /// constraint row bodies × [`LINEAR_UNITS_PER_BODY_ROW`], plus nv m² for the rows' Gram
    /// matrix and m³ for its solve (m rows): O(n m² + m³).
    pub linear: Option<f64>,
    /// Moving bodies (for messages).
    pub bodies: usize,
}

impl EvaluationCost {
    /// The cost of `sys`'s dynamics on the path its prediction stages take.
    pub fn of(sys: &crate::System) -> Self {
        let model = sys.model();
        let rows = sys.constraints().nrows;
        let linear = sys.takes_linear_path()
            && (rows == 0 || sys.formulation() != crate::dynamics::Formulation::Embedded);
        Self {
            dense: dense_evaluation_cost(model),
            linear: linear.then(|| linear_evaluation_cost(model, rows)),
            bodies: model.nbodies() - 1,
        }
    }

    /// Work units of one evaluation by a method: explicit ones evaluate on the system's path;
    /// `implicit` ones (a Jacobian and a factor of it) at the dense path's cost.
    pub fn per_evaluation(&self, implicit: bool) -> f64 {
        match self.linear {
            Some(c) if !implicit => c,
            _ => self.dense,
        }
    }

    /// The path `per_evaluation(implicit)` counts, for messages.
    pub fn path(&self, implicit: bool) -> &'static str {
        match self.linear {
            Some(_) if !implicit => "linear-time",
            _ => "dense",
        }
    }
}

/// The dense path's cost of one evaluation: bodies plus Σ over velocity coordinates of
/// (depth in the tree)², the operation count of M's sparse factorization.
pub fn dense_evaluation_cost(model: &crate::Model) -> f64 {
    let mut depth = vec![0.0f64; model.nv];
    let mut cost = model.nbodies() as f64;
    for k in 0..model.nv {
        let p = model.v_parent[k];
        depth[k] = if p == usize::MAX { 1.0 } else { depth[p] + 1.0 };
        cost += depth[k] * depth[k];
    }
    cost
}

/// The linear-time path's cost of one evaluation with `rows` constraint rows
/// ([`EvaluationCost::linear`]).
pub fn linear_evaluation_cost(model: &crate::Model, rows: usize) -> f64 {
    let (bodies, nv, m) = (model.nbodies() as f64, model.nv as f64, rows as f64);
    bodies * (LINEAR_UNITS_PER_BODY + m * LINEAR_UNITS_PER_BODY_ROW) + nv * m * m + m * m * m
}

/// A number for a message: plain where that reads well, `1e308` rather than 309 digits.
pub fn show(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-4..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}
