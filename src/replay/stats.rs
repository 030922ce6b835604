//! The figures of an evaluation: order statistics of the errors, and how often the errors fall
//! inside the predicted covariance's regions.
//!
//! For a Gaussian error e of covariance S in k = 3 dimensions (x, y, yaw), the normalised
//! estimation error squared NEES = eᵀ S⁻¹ e follows χ²(3): its mean is 3, and e lies inside the
//! p-probability region of S when NEES ≤ the χ²(3) quantile of p. A covariance that states the
//! real errors gives coverage ≈ p; below p it is too small (over-confident), above too large.

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

/// The fraction of errors inside the predicted covariance's 50 % and 95 % regions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Coverage {
    /// Fraction with NEES ≤ [`CHI2_3_P50`] (≈ 0.50 when the covariance is right).
    pub p50: f64,
    /// Fraction with NEES ≤ [`CHI2_3_P95`] (≈ 0.95 when the covariance is right).
    pub p95: f64,
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
    /// Of the NEES values `nees` (not empty).
    pub fn of(nees: &[f64]) -> Coverage {
        let n = nees.len() as f64;
        let inside = |bound: f64| nees.iter().filter(|x| **x <= bound).count() as f64 / n;
        Coverage {
            p50: inside(CHI2_3_P50),
            p95: inside(CHI2_3_P95),
        }
    }
}

/// eᵀ S⁻¹ e of a 3-vector and a 3 × 3 covariance; None when S is not positive definite.
pub fn nees(e: [f64; 3], s: [[f64; 3]; 3]) -> Option<f64> {
    let m = nalgebra::Matrix3::from_fn(|i, j| 0.5 * (s[i][j] + s[j][i]));
    let chol = m.cholesky()?;
    let e = nalgebra::Vector3::from(e);
    let x = chol.solve(&e);
    Some(e.dot(&x)).filter(|x| x.is_finite())
}
