//! The process noise's terms (`uncertainty:` in a scene) and where they enter the covariance.
//!
//! Every term enters already on the constraints: a state index's along T's column at the
//! running P's last projection (the velocity kick's mass-weighted share where the constraints tie
//! the coordinate to others), a generalized force along T [0; M⁻¹ e_i]. Entering at a wheel's
//! velocity alone, off the rolling constraints, a term would reach the base only where P is next
//! projected, the wheel's controller taking part of it back meanwhile, and its share would
//! depend on the projection's cadence (covariance/reading.rs).

use crate::error::{Error, Result};
use crate::model::Model;
use nalgebra::{DMatrix, DVectorViewMut};
use serde::Deserialize;
use std::collections::BTreeMap;

/// `uncertainty:` in a scene.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UncertaintySpec {
    /// Acceleration noise density σ per velocity coordinate name [(m/s²)/√Hz or (rad/s²)/√Hz]
    /// (default: none, 0). On a coordinate the constraints tie to others, the share of the
    /// velocity kick they let through (its mass-weighted projection onto them).
    #[serde(default)]
    pub acceleration_noise: BTreeMap<String, f64>,
    /// Effort noise density σ_τ per velocity coordinate name [(N·m)/√Hz or N/√Hz] (default:
    /// none): a white generalized force on the coordinate, moving through the constrained
    /// dynamics whatever it moves — a wheel's torque from the floor, known only roughly,
    /// accelerates the robot it rolls.
    #[serde(default)]
    pub effort_noise: BTreeMap<String, f64>,
    /// Standard deviation σ_b [rad/s² or m/s²] of an acceleration offset on a
    /// velocity-controlled joint while its controller is saturated, the same through a
    /// prediction: how fast the grip lets the joint follow its command, known only roughly
    /// (covariance/constants.rs; default: none). Projected as the acceleration noise is.
    #[serde(default)]
    pub saturation_bias: BTreeMap<String, f64>,
    /// Slip noise density σ_s per velocity coordinate name [m/√s or rad/√s] (default: none):
    /// a white rate added to the coordinate's position outside its dynamics and the rolling
    /// constraints, so that it drifts as a random walk, var = σ_s² t — the slip a rolling
    /// contact does not express (a wide tyre's residual scrub), as robot_localization's
    /// process noise on the pose.
    #[serde(default)]
    pub slip_noise: BTreeMap<String, f64>,
    /// Standard deviation σ_k [m/s or rad/s] of a rate on the coordinate's position while a
    /// velocity controller is saturated, the same through a prediction: how fast the robot
    /// slides while its wheels skid, which a tyre model knows only roughly
    /// (covariance/constants.rs; default: none).
    #[serde(default)]
    pub saturation_slip: BTreeMap<String, f64>,
}

/// σ² per velocity coordinate of `uncertainty.<field>` (0 where it names none); a name the
/// model does not have, or a σ that is negative or not finite, is an error naming it.
pub(crate) fn noise_variances(
    model: &Model,
    field: &str,
    sigmas: &BTreeMap<String, f64>,
) -> Result<Vec<f64>> {
    let mut out = vec![0.0; model.nv];
    for (name, &sigma) in sigmas {
        let i = (model.v_index(name))
            .map_err(|e| Error::Invalid(format!("uncertainty.{field}: {e}")))?;
        if !(sigma.is_finite() && sigma >= 0.0) {
            return Err(Error::Invalid(format!(
                "uncertainty.{field}.{name} = {sigma}: must be finite and ≥ 0"
            )));
        }
        out[i] = sigma * sigma;
    }
    Ok(out)
}

/// The scene's noise variances per velocity coordinate, and the directions they enter along.
#[derive(Clone, Debug)]
pub(super) struct NoiseTerms {
    /// σ_i² of the acceleration noise.
    acceleration: Vec<f64>,
    /// σ_τ,i² of the effort noise.
    effort: Vec<f64>,
    /// σ_s,i² of the slip noise on the coordinate's position.
    slip: Vec<f64>,
    /// σ_b² of the grip bias (covariance/constants.rs).
    pub saturation_bias: Vec<f64>,
    /// σ_k² of the skid's rate on the coordinate's position (covariance/constants.rs).
    pub saturation_slip: Vec<f64>,
    /// T at the running P's last projection (identity without constraints): a term entering
    /// at state index e enters along its column e.
    pub entry_proj: DMatrix<f64>,
    /// T [0; M⁻¹] at the same projection (2nv × nv): column i is where a unit generalized
    /// force on velocity coordinate i enters.
    effort_entry: DMatrix<f64>,
    /// u and (A − I) u of the term being added.
    entry: Vec<f64>,
    response: Vec<f64>,
}

impl NoiseTerms {
    /// From the scene's `uncertainty:`; a name the model does not have, or a bad σ, is an
    /// error naming it.
    pub fn new(model: &Model, spec: &UncertaintySpec) -> Result<Self> {
        let nv = model.nv;
        Ok(Self {
            acceleration: noise_variances(model, "acceleration_noise", &spec.acceleration_noise)?,
            effort: noise_variances(model, "effort_noise", &spec.effort_noise)?,
            slip: noise_variances(model, "slip_noise", &spec.slip_noise)?,
            saturation_bias: noise_variances(model, "saturation_bias", &spec.saturation_bias)?,
            saturation_slip: noise_variances(model, "saturation_slip", &spec.saturation_slip)?,
            entry_proj: DMatrix::identity(2 * nv, 2 * nv),
            effort_entry: DMatrix::zeros(2 * nv, nv),
            entry: vec![0.0; 2 * nv],
            response: vec![0.0; 2 * nv],
        })
    }

    /// Whether a generalized force enters: the projection must then form M⁻¹ even without
    /// constraints.
    pub fn effort_enters(&self) -> bool {
        self.effort.iter().any(|&s2| s2 > 0.0)
    }

    /// The directions at a projection: T (`proj`, where `constrained`; I stays otherwise) and
    /// M⁻¹ (`minv`, read where effort noise enters).
    pub fn enter_at(&mut self, constrained: bool, proj: &DMatrix<f64>, minv: &DMatrix<f64>) {
        if constrained {
            self.entry_proj.copy_from(proj);
        }
        if self.effort_enters() {
            let nv = minv.nrows();
            (self.effort_entry).gemm(1.0, &self.entry_proj.columns(nv, nv), minv, 0.0);
        }
    }

    /// Adds Q_h of a chunk of length h [s] with transition `a` to `p` (mod.rs,
    /// `apply_linearization`): acceleration noise along T's column of δv_i, slip noise along
    /// that of δq_i, effort noise along T [0; M⁻¹ e_i] — the same integral.
    pub fn add_white(&mut self, p: &mut DMatrix<f64>, a: &DMatrix<f64>, h: f64) {
        let nv = self.acceleration.len();
        let white =
            (self.acceleration.iter().enumerate()).map(|(i, &s2)| (Entry::State(nv + i), s2));
        let slip = (self.slip.iter().enumerate()).map(|(i, &s2)| (Entry::State(i), s2));
        let effort = (self.effort.iter().enumerate()).map(|(i, &s2)| (Entry::Effort(i), s2));
        for (entry, s2) in white.chain(slip).chain(effort).filter(|&(_, s2)| s2 > 0.0) {
            let (u, d) = (&mut self.entry, &mut self.response);
            let (columns, e) = match entry {
                Entry::State(e) => (&self.entry_proj, e),
                Entry::Effort(i) => (&self.effort_entry, i),
            };
            entry_response(a, columns, e, u, d);
            let w = |r: usize| u[r] + d[r] / 2.0;
            for c in 0..2 * nv {
                let (wc, dc) = (w(c), d[c]);
                if wc == 0.0 && dc == 0.0 {
                    continue;
                }
                for r in 0..2 * nv {
                    p[(r, c)] += h * s2 * (w(r) * wc + d[r] * dc / 12.0);
                }
            }
        }
    }
}

/// Where a noise term enters: a state index (a velocity's or a position's), or a velocity
/// coordinate's generalized force.
#[derive(Clone, Copy)]
enum Entry {
    State(usize),
    Effort(usize),
}

/// Noise entering at state index e: `u = T e` (T's column e: the entry brought onto the
/// constraints) and `d = (A − I) u` (how the chunk's transition A moves it).
fn entry_response(a: &DMatrix<f64>, t: &DMatrix<f64>, e: usize, u: &mut [f64], d: &mut [f64]) {
    let column = t.column(e);
    u.copy_from_slice(column.as_slice());
    let n = d.len();
    let mut d = DVectorViewMut::from_slice(d, n);
    d.gemv(1.0, a, &column, 0.0);
    d -= column;
}
