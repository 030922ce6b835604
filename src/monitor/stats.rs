//! The monitor's statistics: a bounded window of the latest values with its median, and the
//! normalised estimation error squared (NEES) of a planar pose error.

/// The latest `capacity` values (older ones are overwritten), allocation-free after
/// construction.
#[derive(Clone, Debug)]
pub struct Window {
    values: Vec<f64>,
    next: usize,
    len: usize,
}

impl Window {
    /// An empty window of `capacity` (≥ 1) values.
    pub fn new(capacity: usize) -> Self {
        Window {
            values: vec![0.0; capacity.max(1)],
            next: 0,
            len: 0,
        }
    }

    /// Adds `x`, replacing the oldest value when full.
    pub fn push(&mut self, x: f64) {
        self.values[self.next] = x;
        self.next = (self.next + 1) % self.values.len();
        self.len = (self.len + 1).min(self.values.len());
    }

    /// How many values it holds.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Forgets every value.
    pub fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }

    /// The values held, oldest first not guaranteed.
    fn held(&self) -> &[f64] {
        &self.values[..self.len]
    }

    /// The mean of the values (NaN when empty).
    pub fn mean(&self) -> f64 {
        match self.len {
            0 => f64::NAN,
            n => self.held().iter().sum::<f64>() / n as f64,
        }
    }

    /// The median of the values (the mean of the two middle ones for an even count; NaN when
    /// empty), sorted in `scratch` (≥ the capacity; no allocation).
    pub fn median(&self, scratch: &mut [f64]) -> f64 {
        let n = self.len;
        if n == 0 {
            return f64::NAN;
        }
        let s = &mut scratch[..n];
        s.copy_from_slice(self.held());
        let cmp = |a: &f64, b: &f64| a.total_cmp(b);
        let (lower, hi, _) = s.select_nth_unstable_by(n / 2, cmp);
        let hi = *hi;
        match n % 2 {
            1 => hi,
            _ => {
                let lo = lower.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                0.5 * (lo + hi)
            }
        }
    }
}

/// A planar pose (x [m], y [m], yaw [rad]) in the odom frame.
pub type PlanarPose = [f64; 3];

/// A 3×3 covariance of (x, y, yaw) [m², m·rad, rad²], row-major.
pub type PlanarCovariance = [[f64; 3]; 3];

/// `a − b` for yaw angles, wrapped to (−π, π] [rad].
pub fn yaw_difference(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    if d > std::f64::consts::PI {
        d - std::f64::consts::TAU
    } else {
        d
    }
}

/// The NEES eᵀ S⁻¹ e of the error `e` = (dx, dy, dyaw) under `s` = the predicted plus the
/// measured covariance; None when `s` is not symmetric positive definite (a Cholesky
/// factorization S = L Lᵀ fails) or the result is not finite. Under a consistent model e ~
/// N(0, S) and the NEES is χ² with 3 degrees of freedom: mean 3, median 2.366.
pub fn nees(e: [f64; 3], s: &PlanarCovariance) -> Option<f64> {
    let mut l = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let sum: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            let sym = 0.5 * (s[i][j] + s[j][i]);
            if i == j {
                let d = sym - sum;
                if d.is_nan() || d <= 0.0 {
                    return None;
                }
                l[i][i] = d.sqrt();
            } else {
                l[i][j] = (sym - sum) / l[j][j];
            }
        }
    }
    // Forward substitution L z = e: NEES = |z|².
    let mut z = [0.0; 3];
    for i in 0..3 {
        let sum: f64 = (0..i).map(|k| l[i][k] * z[k]).sum();
        z[i] = (e[i] - sum) / l[i][i];
    }
    let n = z.iter().map(|x| x * x).sum::<f64>();
    n.is_finite().then_some(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_of_a_full_window_is_that_of_its_latest_values() {
        let mut w = Window::new(4);
        let mut scratch = [0.0; 4];
        assert!(w.median(&mut scratch).is_nan());
        for x in [100.0, 3.0, 1.0, 2.0] {
            w.push(x);
        }
        assert_eq!(w.median(&mut scratch), 2.5);
        w.push(5.0); // 100 leaves: {3, 1, 2, 5}
        assert_eq!(w.median(&mut scratch), 2.5);
        w.push(0.0); // {1, 2, 5, 0}
        assert_eq!(w.median(&mut scratch), 1.5);
        assert_eq!(w.mean(), 2.0);
        let mut odd = Window::new(3);
        for x in [7.0, -1.0, 4.0] {
            odd.push(x);
        }
        assert_eq!(odd.median(&mut scratch), 4.0);
    }

    #[test]
    fn nees_of_a_diagonal_covariance_is_the_sum_of_squared_z_scores() {
        let s = [[4e-6, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 4e-4]];
        // (2σx, 1σy, 0.5σyaw): 4 + 1 + 0.25.
        let n = nees([4e-3, 1e-3, 1e-2], &s).unwrap();
        assert!((n - 5.25).abs() < 1e-12, "{n}");
        // A correlated 2×2 block: S = [[1, ρ], [ρ, 1]], e = (1, 1) → 2 / (1 + ρ).
        let s = [[1.0, 0.5, 0.0], [0.5, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let n = nees([1.0, 1.0, 0.0], &s).unwrap();
        assert!((n - 2.0 / 1.5).abs() < 1e-12, "{n}");
        let singular = [[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(nees([1.0, 0.0, 0.0], &singular), None);
    }

    #[test]
    fn yaw_differences_wrap_across_pi() {
        let d = yaw_difference(-3.1, 3.1);
        assert!((d - (std::f64::consts::TAU - 6.2)).abs() < 1e-12, "{d}");
        assert!((yaw_difference(0.3, 0.1) - 0.2).abs() < 1e-15);
    }
}
