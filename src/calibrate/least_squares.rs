//! The fit: Levenberg–Marquardt (the `levenberg-marquardt` crate, MINPACK's algorithm) on the
//! replayed predictions' errors, over parameters scaled to the size a change must reach to
//! matter ([`SceneParameters::scale`]).
//!
//! A residual is one error of one prediction — Δx, Δy [m] or Δyaw [rad] between the reference
//! and the prediction at its horizon — divided by that kind's RMS at that horizon at the scene's
//! own values, so that every horizon and both kinds weigh alike; once the process noise is
//! known, the prediction's (Δx, Δy, Δyaw) whitened by its predicted covariance instead
//! (`weighting.rs`). The Jacobian is taken by
//! central differences of the whole replay: a fitted value changes the model, the controllers'
//! response and the start's projection at once, which no analytic derivative of the core
//! covers. The fitted values' covariance is a sandwich over the replay's starts ([`spread`]):
//! predictions from nearby starts share their errors.

use super::Problem;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};

/// A replay that failed for a trial value (e.g. a radius the model refuses) counts as an error
/// this many times its kind's RMS: the step is rejected and the trust region shrinks.
const FAILED_RESIDUAL: f64 = 1e3;
/// The central difference's step, in scaled units (a twentieth of a parameter's scale).
const STEP: f64 = 0.05;

/// The least-squares problem the crate minimizes: `x` the scaled offsets from the scene's
/// values.
pub(super) struct Fit<'a> {
    pub problem: &'a Problem<'a>,
    pub x: DVector<f64>,
}

impl Fit<'_> {
    /// The residuals at scaled offsets `x`; `None` if the replay fails.
    pub fn residuals_at(&self, x: &DVector<f64>) -> Option<DVector<f64>> {
        self.problem.residuals(x.as_slice()).ok()
    }

    /// ∂r/∂x by central differences; a failed side falls back to a one-sided difference.
    pub fn jacobian_at(&self, x: &DVector<f64>) -> Option<DMatrix<f64>> {
        let mut j = DMatrix::zeros(self.problem.residual_count(), x.len());
        // The residuals at x itself only where a side fails: LM has them already.
        let at_x = std::cell::OnceCell::new();
        let center = || at_x.get_or_init(|| self.residuals_at(x)).clone();
        for k in 0..x.len() {
            let mut plus = x.clone();
            plus[k] += STEP;
            let mut minus = x.clone();
            minus[k] -= STEP;
            let col = match (self.residuals_at(&plus), self.residuals_at(&minus)) {
                (Some(p), Some(m)) => (p - m) / (2.0 * STEP),
                (Some(p), None) => (p - center()?) / STEP,
                (None, Some(m)) => (center()? - m) / STEP,
                (None, None) => return None,
            };
            j.set_column(k, &col);
        }
        Some(j)
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Fit<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.x.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.x.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        Some(self.residuals_at(&self.x).unwrap_or_else(|| {
            DVector::from_element(self.problem.residual_count(), FAILED_RESIDUAL)
        }))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        self.jacobian_at(&self.x)
    }
}

/// The minimum near scaled offsets `x0`: (scaled offsets, termination as text).
pub(super) fn minimize(
    problem: &Problem,
    x0: DVector<f64>,
    max_iterations: usize,
) -> (DVector<f64>, String) {
    let fit = Fit { problem, x: x0 };
    // ftol 1e-4: a relative change of the cost below that is below what the recordings'
    // noise determines; the crate's default (30 ε) would spend replays on round-off.
    let lm = LevenbergMarquardt::new()
        .with_ftol(1e-4)
        .with_xtol(1e-4)
        .with_gtol(1e-8)
        .with_patience(max_iterations.max(1));
    let (fit, report) = lm.minimize(fit);
    (fit.x.clone(), format!("{:?}", report.termination))
}

/// The fitted values' covariance, in scaled units, and which of them the recordings move at
/// all (where JᵀJ is singular along a value, nothing in them determines it).
pub(super) struct Spread {
    covariance: DMatrix<f64>,
    determined: Vec<bool>,
}

impl Spread {
    /// Value `k`'s standard error; `None` where not determined.
    fn std_error(&self, k: usize) -> Option<f64> {
        let se = self.covariance[(k, k)].max(0.0).sqrt();
        (self.determined[k] && se.is_finite()).then_some(se)
    }

    /// Each value's standard error; `None` where not determined.
    pub fn std_errors(&self) -> Vec<Option<f64>> {
        (0..self.determined.len())
            .map(|k| self.std_error(k))
            .collect()
    }

    /// The correlation of values `a` and `b`; `None` where either is not determined or has no
    /// spread.
    pub fn correlation(&self, a: usize, b: usize) -> Option<f64> {
        let [sa, sb] = [a, b].map(|k| self.std_error(k).filter(|s| *s > 0.0));
        Some(self.covariance[(a, b)] / (sa? * sb?)).filter(|c| c.is_finite())
    }
}

/// The spread of the fitted scaled offsets, from the Jacobian J and the residuals r at them,
/// residual row i belonging to start `starts[i]` = (recording, the start's rank in it).
///
/// The predictions of nearby starts overlap in time and share their errors (the same skid,
/// the same odometry message as one's reference and another's start), so the rows are not
/// independent and Gauss–Newton's s² (JᵀJ)⁻¹ understates the spread. The covariance is the
/// sandwich (JᵀJ)⁻¹ Ω (JᵀJ)⁻¹ · m/(m − p) of Hansen and Hodrick (1980), the covariance
/// of a regression on overlapping forecast errors: Ω sums g_s g_tᵀ over every pair of starts
/// of one recording at most `lags` ranks apart, g_s = Σ Jᵢᵀ rᵢ over start s's rows. Should
/// that sum not be positive semi-definite (it need not be in a short recording), the pairs
/// are weighed by Newey and West's 1 − lag/(lags + 1), which always is.
pub(super) fn spread(
    j: &DMatrix<f64>,
    r: &DVector<f64>,
    starts: &[(usize, usize)],
    lags: usize,
) -> Spread {
    let (m, p) = j.shape();
    let jtj = j.transpose() * j;
    let svd = jtj.clone().svd(true, true);
    let top = svd.singular_values.max();
    let Ok(inv) = svd.pseudo_inverse(1e-10 * top.max(f64::MIN_POSITIVE)) else {
        return Spread {
            covariance: DMatrix::from_element(p, p, f64::NAN),
            determined: vec![false; p],
        };
    };
    // Each start's score g_s, in the order the starts first appear.
    let mut scores: Vec<((usize, usize), DVector<f64>)> = Vec::new();
    for (i, start) in starts.iter().enumerate().take(m) {
        let g = j.row(i).transpose() * r[i];
        match scores.iter_mut().find(|(s, _)| s == start) {
            Some((_, sum)) => *sum += g,
            None => scores.push((*start, g)),
        }
    }
    let omega = |weighted: bool| {
        let mut omega = DMatrix::zeros(p, p);
        for (a, ga) in &scores {
            for (b, gb) in &scores {
                let lag = a.1.abs_diff(b.1);
                if a.0 != b.0 || lag > lags {
                    continue;
                }
                let w = if weighted {
                    1.0 - lag as f64 / (lags + 1) as f64
                } else {
                    1.0
                };
                omega += w * ga * gb.transpose();
            }
        }
        omega
    };
    let positive = |o: &DMatrix<f64>| {
        let e = o.clone().symmetric_eigen().eigenvalues;
        e.min() >= -1e-12 * e.amax()
    };
    let mut o = omega(false);
    if !positive(&o) {
        o = omega(true);
    }
    let scale = m as f64 / m.saturating_sub(p).max(1) as f64;
    Spread {
        covariance: scale * &inv * o * &inv,
        determined: (0..p).map(|k| jtj[(k, k)] > 1e-10 * top).collect(),
    }
}

#[cfg(test)]
#[path = "least_squares_tests.rs"]
mod tests;
