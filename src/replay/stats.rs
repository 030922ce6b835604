//! The figures of an evaluation: order statistics of the errors, and how often the errors fall
//! inside the predicted covariance's regions.
//!
//! For a Gaussian error e of covariance S in k = 3 dimensions (x, y, yaw), the normalised
//! estimation error squared NEES = eᵀ S⁻¹ e follows χ²(3): its mean is 3, and e lies inside the
//! p-probability region of S when NEES ≤ the χ²(3) quantile of p. A covariance that states the
//! real errors gives coverage ≈ p; below p it is too small (over-confident), above too large.
//!
//! A coverage counted on a few dozen predictions is itself uncertain, the more so as
//! predictions from nearby starts overlap in time and share their errors. Each fraction comes
//! with a 95 % Wilson score interval on an effective count of independent predictions
//! ([`independent_count`]): a covariance whose interval holds p may be right, one whose
//! interval does not is not.

use serde::Serialize;

/// The χ²(3) quantile of 0.5: the 50 % region's NEES bound.
pub const CHI2_3_P50: f64 = 2.365_973_884_375_338;
/// The χ²(3) quantile of 0.95: the 95 % region's NEES bound.
pub const CHI2_3_P95: f64 = 7.814_727_903_251_178;

/// Median, 95th percentile and maximum of a set of values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Maximum.
    pub max: f64,
}

/// The normal quantile of 0.975: a two-sided 95 % interval's half-width in standard errors.
const Z_95: f64 = 1.959_963_984_540_054;

/// The fraction of errors inside the predicted covariance's 50 % and 95 % regions, each with
/// its 95 % interval.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Coverage {
    /// Fraction with NEES ≤ [`CHI2_3_P50`] (≈ 0.50 when the covariance is right).
    pub p50: f64,
    /// Fraction with NEES ≤ [`CHI2_3_P95`] (≈ 0.95 when the covariance is right).
    pub p95: f64,
    /// 95 % Wilson score interval of the fraction inside the 50 % region, [low, high].
    pub p50_interval: [f64; 2],
    /// The same of the fraction inside the 95 % region.
    pub p95_interval: [f64; 2],
    /// The effective count of independent predictions the intervals rest on
    /// ([`independent_count`]).
    pub independent_predictions: f64,
}

/// The p-quantile (0 ≤ p ≤ 1) of `sorted` (ascending, not empty), interpolated linearly between
/// the order statistics at rank p (n − 1) — the common definition (NumPy's default).
pub fn quantile(sorted: &[f64], p: f64) -> f64 {
    let r = p * (sorted.len() - 1) as f64;
    let (i, f) = (r.floor() as usize, r - r.floor());
    match sorted.get(i + 1) {
        Some(next) => sorted[i] + f * (next - sorted[i]),
        None => sorted[i],
    }
}

impl Spread {
    /// Of `values` (not empty, finite).
    pub fn of(values: &[f64]) -> Spread {
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        Spread {
            median: quantile(&v, 0.5),
            p95: quantile(&v, 0.95),
            max: v[v.len() - 1],
        }
    }
}

impl Coverage {
    /// Of the NEES values `nees` (not empty), taken as independent.
    pub fn of(nees: &[f64]) -> Coverage {
        Coverage::of_overlapping(nees, 1.0, 0.0)
    }

    /// Of the NEES values `nees` (not empty) of predictions of horizon `horizon_s` started
    /// every `every_s` seconds ([`independent_count`]).
    pub fn of_overlapping(nees: &[f64], every_s: f64, horizon_s: f64) -> Coverage {
        let n = nees.len() as f64;
        let inside = |bound: f64| nees.iter().filter(|x| **x <= bound).count() as f64 / n;
        let (p50, p95) = (inside(CHI2_3_P50), inside(CHI2_3_P95));
        let m = independent_count(nees.len(), every_s, horizon_s);
        Coverage {
            p50,
            p95,
            p50_interval: wilson_interval(p50, m),
            p95_interval: wilson_interval(p95, m),
            independent_predictions: m,
        }
    }
}

/// The effective count of independent predictions among `n` of horizon `horizon_s` [s] started
/// every `every_s` [s]: n / (1 + 2 Σ_ℓ ρ_ℓ²), ρ_ℓ = 1 − ℓ every/h over the lags ℓ at which two
/// predictions overlap. Errors that build up over a prediction from independent increments (a
/// random walk, a skid here and there) correlate between two predictions as the share of
/// their spans they have in common, ρ_ℓ; an event of a radially symmetric function of a
/// Gaussian error, such as NEES ≤ bound, correlates as ρ² to leading order (its Hermite
/// expansion has no first-order term) and less beyond. Without overlap, n.
pub fn independent_count(n: usize, every_s: f64, horizon_s: f64) -> f64 {
    let mut sum = 0.0;
    if every_s > 0.0 && horizon_s > every_s {
        let mut lag = 1.0;
        while lag * every_s < horizon_s {
            sum += (1.0 - lag * every_s / horizon_s).powi(2);
            lag += 1.0;
        }
    }
    n as f64 / (1.0 + 2.0 * sum)
}

/// The 95 % Wilson score interval of a fraction `p` observed among `n` (> 0) independent
/// trials: [low, high], inside [0, 1] and not degenerate at 0 or 1 (Wilson, 1927).
pub fn wilson_interval(p: f64, n: f64) -> [f64; 2] {
    let z2 = Z_95 * Z_95;
    let d = 1.0 + z2 / n;
    let centre = (p + z2 / (2.0 * n)) / d;
    let half = Z_95 * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt() / d;
    [(centre - half).max(0.0), (centre + half).min(1.0)]
}

/// eᵀ S⁻¹ e of a 3-vector and a 3 × 3 covariance; None when S is not positive definite.
pub fn nees(e: [f64; 3], s: [[f64; 3]; 3]) -> Option<f64> {
    let m = nalgebra::Matrix3::from_fn(|i, j| 0.5 * (s[i][j] + s[j][i]));
    let chol = m.cholesky()?;
    let e = nalgebra::Vector3::from(e);
    let x = chol.solve(&e);
    Some(e.dot(&x)).filter(|x| x.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    /// Wilson's interval against its closed forms: all n inside gives [n/(n + z²), 1], and
    /// Newcombe's worked example (Stat. Med. 17, 857, 1998), 81 of 263: [0.2553, 0.3662].
    #[test]
    fn wilson_interval_matches_its_closed_forms() {
        let z2 = Z_95 * Z_95;
        let [lo, hi] = wilson_interval(1.0, 38.0);
        assert!(
            (lo - 38.0 / (38.0 + z2)).abs() < 1e-15 && (hi - 1.0).abs() < 1e-15,
            "{lo} {hi}"
        );
        let [lo, hi] = wilson_interval(81.0 / 263.0, 263.0);
        assert!(
            (lo - 0.2553).abs() < 5e-5 && (hi - 0.3662).abs() < 5e-5,
            "{lo} {hi}"
        );
    }

    /// Predictions whose errors are a random walk's increments over overlapping spans (2 s
    /// horizons started every 0.5 s over 20 s, as `evaluate` scores a drive): the interval on
    /// the effective count holds the true 0.95 in at least 95 % of 4000 simulated drives and
    /// is not much wider than it must be (at most 99 %), where one counting every prediction
    /// as independent holds it far less often (90 %).
    #[test]
    fn coverage_intervals_hold_the_truth_on_overlapping_predictions() {
        let mut rng = Rng(0x5eed_c0de);
        let (every, horizon, steps): (f64, f64, usize) = (0.5, 2.0, 40);
        let lag = (horizon / every) as usize;
        let (mut held, mut held_naive, drives) = (0, 0, 4000);
        for _ in 0..drives {
            // A 3-axis walk of unit rate sampled every 0.5 s: each step's increment is N(0, 0.5).
            let mut w = vec![[0.0f64; 3]; steps + 1];
            for k in 1..=steps {
                for a in 0..3 {
                    w[k][a] = w[k - 1][a] + every.sqrt() * rng.normal();
                }
            }
            let nees: Vec<f64> = (0..=steps - lag)
                .map(|i| {
                    (0..3)
                        .map(|a| (w[i + lag][a] - w[i][a]).powi(2))
                        .sum::<f64>()
                        / horizon
                })
                .collect();
            let c = Coverage::of_overlapping(&nees, every, horizon);
            held += usize::from(c.p95_interval[0] <= 0.95 && 0.95 <= c.p95_interval[1]);
            let naive = Coverage::of(&nees).p95_interval;
            held_naive += usize::from(naive[0] <= 0.95 && 0.95 <= naive[1]);
        }
        let (rate, naive) = (
            held as f64 / drives as f64,
            held_naive as f64 / drives as f64,
        );
        assert!((0.95..=0.99).contains(&rate), "held {rate}");
        assert!(naive < 0.92, "naive {naive}");
    }

    /// Without overlap every prediction counts; 1 s horizons every 0.5 s count as n / 1.5.
    #[test]
    fn the_independent_count_follows_the_overlap() {
        assert_eq!(independent_count(40, 0.5, 0.25), 40.0);
        assert_eq!(independent_count(40, 0.5, 0.5), 40.0);
        assert!((independent_count(39, 0.5, 1.0) - 26.0).abs() < 1e-12);
        // Lags 1, 2, 3 at 2 s: 1 + 2 (0.75² + 0.5² + 0.25²) = 2.75.
        assert!((independent_count(37, 0.5, 2.0) - 37.0 / 2.75).abs() < 1e-12);
    }
}
