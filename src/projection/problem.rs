//! The projection problem in coordinate order (what the solver reads), its validation, and the
//! effective per-coordinate bounds with the source of each.

use crate::error::{Error, Result, check_finite, check_len};
use crate::model::{JointKind, Model};
use nalgebra::DMatrix;
use serde::Serialize;

/// Acceleration limit `|v_i − v_current,i| ≤ a_max,i · dt`.
#[derive(Clone, Debug, PartialEq)]
pub struct AccelLimit {
    /// Time step dt [s], > 0.
    pub dt: f64,
    /// a_max per velocity coordinate [m/s² or rad/s²]; `f64::INFINITY` = none.
    pub a_max: Vec<f64>,
    /// The current velocity (nv) [m/s or rad/s].
    pub v_current: Vec<f64>,
}

/// `v* = argmin ½ (v − v_des)ᵀ M(q) (v − v_des)` s.t. `J(q) v = 0`, `lo ≤ v ≤ hi`, `A v ≤ b`.
///
/// `lo`/`hi` combine the URDF velocity limits of 1-DOF joints (when `velocity_limits`), the
/// request's bounds and the acceleration limit; the tightest wins per side. Sizes: nv for every
/// vector, A is m × nv and b has m entries (m = 0: no inequalities).
#[derive(Clone, Debug, PartialEq)]
pub struct ProjectionProblem {
    /// Desired velocity (nv) [m/s, rad/s].
    pub v_des: Vec<f64>,
    /// Bounds the request adds (nv); ±∞ = none. NaN is refused.
    pub lower: Vec<f64>,
    /// Upper bounds the request adds (nv) [m/s, rad/s]; +∞ = none. NaN is refused.
    pub upper: Vec<f64>,
    /// Apply the URDF `<limit velocity>` of revolute and prismatic joints (default true).
    pub velocity_limits: bool,
    /// Optional acceleration limit, turned into bounds `v_current ± a_max · dt`.
    pub accel_limit: Option<AccelLimit>,
    /// User inequalities A v ≤ b (m × nv, m).
    pub a: DMatrix<f64>,
    /// Right-hand side b of A v ≤ b (m).
    pub b: Vec<f64>,
}

impl ProjectionProblem {
    /// Zero desired velocity, no bounds but the URDF limits, no inequalities.
    pub fn new(model: &Model) -> Self {
        let nv = model.nv;
        Self {
            v_des: vec![0.0; nv],
            lower: vec![f64::NEG_INFINITY; nv],
            upper: vec![f64::INFINITY; nv],
            velocity_limits: true,
            accel_limit: None,
            a: DMatrix::zeros(0, nv),
            b: vec![],
        }
    }

    /// Sizes and finiteness, naming what is wrong.
    pub fn validate(&self, nv: usize) -> Result<()> {
        check_len("v_des", &self.v_des, nv)?;
        check_finite("v_des", &self.v_des)?;
        check_len("lower", &self.lower, nv)?;
        check_len("upper", &self.upper, nv)?;
        check_not_nan("lower", &self.lower)?;
        check_not_nan("upper", &self.upper)?;
        if let Some(al) = &self.accel_limit {
            if !(al.dt.is_finite() && al.dt > 0.0) {
                return Err(Error::Invalid(format!(
                    "accel_limit.dt = {} s must be positive and finite",
                    al.dt
                )));
            }
            check_len("accel_limit.a_max", &al.a_max, nv)?;
            check_not_nan("accel_limit.a_max", &al.a_max)?;
            if let Some(i) = al.a_max.iter().position(|&x| x < 0.0) {
                return Err(Error::Invalid(format!(
                    "accel_limit.a_max entry {i} is negative ({})",
                    al.a_max[i]
                )));
            }
            check_len("accel_limit.v_current", &al.v_current, nv)?;
            check_finite("accel_limit.v_current", &al.v_current)?;
        }
        let m = self.a.nrows();
        if m > 0 && self.a.ncols() != nv {
            return Err(Error::Dimension {
                what: "A (columns)".into(),
                expected: nv,
                got: self.a.ncols(),
            });
        }
        check_len("b", &self.b, m)?;
        check_finite("A", self.a.as_slice())?;
        check_finite("b", &self.b)
    }
}

fn check_not_nan(what: &str, x: &[f64]) -> Result<()> {
    match x.iter().position(|v| v.is_nan()) {
        Some(index) => Err(Error::NonFinite {
            what: what.to_string(),
            index,
            value: x[index],
        }),
        None => Ok(()),
    }
}

/// Where a bound comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundSource {
    /// `<limit velocity>` of the joint in the URDF.
    UrdfVelocityLimit,
    /// The request's `lower` / `upper`.
    Request,
    /// `v_current ± a_max · dt`.
    AccelerationLimit,
}

impl BoundSource {
    /// Human-readable source, used in conflict labels.
    pub fn label(self) -> &'static str {
        match self {
            BoundSource::UrdfVelocityLimit => "URDF velocity limit",
            BoundSource::Request => "request",
            BoundSource::AccelerationLimit => "acceleration limit",
        }
    }
}

/// Lower or upper.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// Lower bound, v_i ≥ lo_i.
    Lower,
    /// Upper bound, v_i ≤ hi_i.
    Upper,
}

/// Effective bounds per coordinate (preallocated, refilled each call).
#[derive(Clone, Debug)]
pub(super) struct Bounds {
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
    pub lo_src: Vec<BoundSource>,
    pub hi_src: Vec<BoundSource>,
}

impl Bounds {
    pub fn new(nv: usize) -> Self {
        Self {
            lo: vec![f64::NEG_INFINITY; nv],
            hi: vec![f64::INFINITY; nv],
            lo_src: vec![BoundSource::Request; nv],
            hi_src: vec![BoundSource::Request; nv],
        }
    }

    /// Tightest of the URDF limit (1-DOF joints only), the request and the acceleration limit.
    pub fn fill(&mut self, model: &Model, p: &ProjectionProblem) {
        let nv = model.nv;
        self.lo.fill(f64::NEG_INFINITY);
        self.hi.fill(f64::INFINITY);
        if p.velocity_limits {
            for b in model.bodies.iter().skip(1) {
                let j = &b.joint;
                if matches!(
                    j.kind,
                    JointKind::Revolute { .. } | JointKind::Prismatic { .. }
                ) {
                    let lim = model.limits.velocity[j.idx_v];
                    if lim.is_finite() {
                        self.tighten(j.idx_v, -lim, lim, BoundSource::UrdfVelocityLimit);
                    }
                }
            }
        }
        for i in 0..nv {
            self.tighten(i, p.lower[i], p.upper[i], BoundSource::Request);
        }
        if let Some(al) = &p.accel_limit {
            for i in 0..nv {
                let w = al.a_max[i] * al.dt;
                if w.is_finite() {
                    let c = al.v_current[i];
                    self.tighten(i, c - w, c + w, BoundSource::AccelerationLimit);
                }
            }
        }
    }

    fn tighten(&mut self, i: usize, lo: f64, hi: f64, src: BoundSource) {
        if lo > self.lo[i] {
            self.lo[i] = lo;
            self.lo_src[i] = src;
        }
        if hi < self.hi[i] {
            self.hi[i] = hi;
            self.hi_src[i] = src;
        }
    }

    /// Any finite bound.
    pub fn any(&self) -> bool {
        self.lo.iter().any(|x| x.is_finite()) || self.hi.iter().any(|x| x.is_finite())
    }
}
