//! How the drive answers its commands, from the scored predictions: a late drive, or one that
//! travels or turns short of its model.
//!
//! A prediction starts from the measured velocity (v₀, ω₀) under a held command (u, ω_u) and
//! lets the model's controllers close the gap d = (u − v₀, ω_u − ω₀). A drive that follows
//! its commands through a first-order lag τ the model does not have closes it τ later, so it
//! ends about τ·d behind: along the predicted chord (the heading halfway through the
//! predicted turn, about which a turn's shortfall moves the position only to second order)
//! the pose error is −τ·d_v, in yaw −τ·d_ω. A drive that travels or turns a fraction short
//! of its model at any speed (worn tyres, scrub) leaves errors k_v·u·h and k_ω·ω_u·h over
//! the horizon h instead, proportional to the command, not to the gap. Over the window, each
//! scored prediction gives two rows, each divided by its error's standard deviation (the
//! predicted covariance plus the odometry's, along the chord and in yaw):
//!
//! e_s = −τ d_v + k_v u h,   e_ψ = −τ d_ω + k_ω ω_u h,
//!
//! fitted by least squares for (τ, k_v, k_ω), with τ's standard error from the residual. Under
//! smooth commands the gap is itself proportional to the command (the model's own steady
//! shortfall) and τ is then poorly determined, which its standard error says; after steps the
//! gap decays while the command holds, and the two tell apart.

use nalgebra::{Matrix3, Vector3};

/// The fitted response over a horizon's window.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ResponseFit {
    /// Predictions fitted.
    pub samples: usize,
    /// τ: how much later than its model the drive closes a gap to its command [s].
    pub lag_s: f64,
    /// τ's standard error [s].
    pub lag_std_error_s: f64,
    /// k_v: the fraction of the commanded speed × horizon the base travels beyond its model
    /// (negative: short) [1].
    pub travel_ratio: f64,
    /// k_ω: the fraction of the commanded turn rate × horizon the base turns beyond its model
    /// (negative: short) [1].
    pub turn_ratio: f64,
}

/// One prediction's rows: (e, −d, u·h) along the chord and in yaw, each over its σ.
type Rows = [[f64; 3]; 2];

/// A ring of the last `capacity` predictions' rows.
#[derive(Clone, Debug)]
pub struct ResponseWindow {
    rows: Vec<Rows>,
    next: usize,
    len: usize,
}

/// What one scored prediction contributes: its pose error (measured − predicted: x, y [m],
/// yaw [rad]), the predicted yaw at its end [rad], the error's covariance (predicted plus
/// measured), the command it held and the measured velocity at its start (v [m/s], ω [rad/s]),
/// and its horizon [s].
pub struct ScoredResponse<'a> {
    /// [m, m, rad]
    pub error: [f64; 3],
    /// [rad]
    pub predicted_yaw: f64,
    /// [m², m·rad, rad²]
    pub covariance: &'a [[f64; 3]; 3],
    /// [m/s, rad/s]
    pub command: [f64; 2],
    /// [m/s, rad/s]
    pub start_velocity: [f64; 2],
    /// [s]
    pub horizon: f64,
}

impl ResponseWindow {
    /// An empty window of `capacity` predictions (at least 1).
    pub fn new(capacity: usize) -> Self {
        Self {
            rows: vec![[[0.0; 3]; 2]; capacity.max(1)],
            next: 0,
            len: 0,
        }
    }

    /// Forgets every prediction.
    pub fn clear(&mut self) {
        self.next = 0;
        self.len = 0;
    }

    /// Adds a scored prediction (one with a non-finite or degenerate part is not taken).
    pub fn push(&mut self, s: &ScoredResponse) {
        let chord = s.predicted_yaw - 0.5 * s.command[1] * s.horizon;
        let (sin, cos) = chord.sin_cos();
        let c = s.covariance;
        let along = cos * cos * c[0][0] + 2.0 * sin * cos * c[0][1] + sin * sin * c[1][1];
        let sigma = [along.sqrt(), c[2][2].sqrt()];
        let e = [cos * s.error[0] + sin * s.error[1], s.error[2]];
        let mut rows = [[0.0; 3]; 2];
        for k in 0..2 {
            rows[k][0] = e[k] / sigma[k];
            rows[k][1] = -(s.command[k] - s.start_velocity[k]) / sigma[k];
            rows[k][2] = s.command[k] * s.horizon / sigma[k];
        }
        if !(sigma.iter().all(|x| *x > 0.0) && rows.iter().flatten().all(|x| x.is_finite())) {
            return;
        }
        let cap = self.rows.len();
        self.rows[self.next] = rows;
        self.next = (self.next + 1) % cap;
        self.len = (self.len + 1).min(cap);
    }

    /// The least-squares (τ, k_v, k_ω) over the window; None below four predictions or where
    /// the rows do not determine all three.
    pub fn fit(&self) -> Option<ResponseFit> {
        if self.len < 4 {
            return None;
        }
        let rows = || self.rows[..self.len].iter();
        // Regressors (−d, u h on its own channel): column 0 is τ, 1 is k_v, 2 is k_ω.
        let regressors = |k: usize, r: &[f64; 3]| match k {
            0 => Vector3::new(r[1], r[2], 0.0),
            _ => Vector3::new(r[1], 0.0, r[2]),
        };
        let (mut a, mut b) = (Matrix3::zeros(), Vector3::zeros());
        for pair in rows() {
            for (k, r) in pair.iter().enumerate() {
                let x = regressors(k, r);
                a += x * x.transpose();
                b += x * r[0];
            }
        }
        let inverse = a.try_inverse()?;
        let p = inverse * b;
        let residual: f64 = rows()
            .flat_map(|pair| pair.iter().enumerate())
            .map(|(k, r)| (r[0] - regressors(k, r).dot(&p)).powi(2))
            .sum();
        let variance = residual / (2 * self.len - 3) as f64;
        let fit = ResponseFit {
            samples: self.len,
            lag_s: p[0],
            lag_std_error_s: (variance * inverse[(0, 0)]).sqrt(),
            travel_ratio: p[1],
            turn_ratio: p[2],
        };
        [
            fit.lag_s,
            fit.lag_std_error_s,
            fit.travel_ratio,
            fit.turn_ratio,
        ]
        .iter()
        .all(|x| x.is_finite())
        .then_some(fit)
    }
}
