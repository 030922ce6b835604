//! The request by name, as a planner, the CLI or a node sends it (JSON), resolved against a model
//! into a [`ProjectionProblem`] in coordinate order.
//!
//! ```json
//! { "base_twist": [1.0, 0.0, 0.5], "joints": {"arm_elbow": 0.3},
//!   "upper": {"left_wheel_joint": 10.0}, "lower": {"vx": -0.2},
//!   "accel_limit": {"dt": 0.05, "a_max": {"vx": 1.0, "wz": 2.0}},
//!   "A": [{"vx": 1.0, "wz": 0.2}], "b": [0.8] }
//! ```
//! or `{ "v_des": [...] }` with all nv values. Coordinates are named as in `v_names`; the base
//! coordinates also as `vx, vy, wz` (planar) or `vx, vy, vz, wx, wy, wz` (floating), base frame.

use super::problem::{AccelLimit, ProjectionProblem};
use crate::error::{Error, Result, check_finite};
use crate::model::{BaseType, Model};
use nalgebra::{DMatrix, DVector};
use serde::Deserialize;
use std::collections::BTreeMap;

/// How coordinates that the request neither names nor covers by the base twist are filled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Fill {
    /// The least-squares, minimum-norm completion of the constraints: wheel speeds follow the
    /// base twist; coordinates no constraint involves get 0.
    #[default]
    Constraints,
    /// Zero.
    Zero,
}

/// Which problem a request poses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// `twist` when the request gives `base_twist`, else `mass`.
    #[default]
    Auto,
    /// The nearest feasible velocity in the kinetic-energy metric M(q) (a QP with the bounds).
    Mass,
    /// Planner semantics (`twist.rs`): nearest in the requested components, then one uniform
    /// scale that satisfies every bound (direction and curvature kept).
    Twist,
}

/// Per-coordinate values by name (`null` = none) or as a full array in coordinate order.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum PerCoordinate {
    /// `{name: value}` by coordinate name or base alias; coordinates not named get none.
    Named(BTreeMap<String, Option<f64>>),
    /// All nv values in coordinate order (`null` = none).
    Dense(Vec<Option<f64>>),
}

/// A row of A: full array in coordinate order, or coefficients by name (others 0).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum RowSpec {
    /// All nv coefficients in coordinate order.
    Dense(Vec<f64>),
    /// `{name: coefficient}` by coordinate name or base alias; others 0.
    Named(BTreeMap<String, f64>),
}

/// `|v_i − v_current,i| ≤ a_max,i · dt`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccelLimitRequest {
    /// Time step [s].
    pub dt: f64,
    /// a_max by coordinate [m/s², rad/s²].
    pub a_max: PerCoordinate,
    /// Current velocity (nv); default: the state's v.
    #[serde(default)]
    pub v_current: Option<Vec<f64>>,
}

/// A projection request by name.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectionRequest {
    /// Full desired velocity (nv) [m/s, rad/s]; or give `base_twist` and/or `joints`.
    #[serde(default)]
    pub v_des: Option<Vec<f64>>,
    /// Desired base twist in the base frame: planar [vx, vy, wz] (or a 6-vector whose vz, wx,
    /// wy are 0), floating [vx, vy, vz, wx, wy, wz] [m/s, rad/s].
    #[serde(default)]
    pub base_twist: Option<Vec<f64>>,
    /// Desired velocities by coordinate name [rad/s or m/s].
    #[serde(default)]
    pub joints: BTreeMap<String, f64>,
    /// Coordinates not given: see [`Fill`].
    #[serde(default)]
    pub fill: Fill,
    /// See [`Mode`].
    #[serde(default)]
    pub mode: Mode,
    /// Extra lower / upper bounds [m/s, rad/s].
    #[serde(default)]
    pub lower: Option<PerCoordinate>,
    /// Extra upper bounds [m/s, rad/s] (see `lower`).
    #[serde(default)]
    pub upper: Option<PerCoordinate>,
    /// Apply the URDF velocity limits (default true).
    #[serde(default = "yes")]
    pub velocity_limits: bool,
    /// Optional acceleration limit `|v_i − v_current,i| ≤ a_max,i · dt` (default none).
    #[serde(default)]
    pub accel_limit: Option<AccelLimitRequest>,
    /// Rows of A v ≤ b.
    #[serde(default, rename = "A")]
    pub a: Vec<RowSpec>,
    /// Right-hand sides b of A v ≤ b, one per row of `A` (default empty).
    #[serde(default)]
    pub b: Vec<f64>,
    /// Control period Δt [s]: the answer is reachable within Δt under the robot's efforts,
    /// friction cones and contacts (the dynamic projection, `dynamic.rs`); 0 (the default) is
    /// the kinematic projection.
    #[serde(default)]
    pub period: f64,
}

fn yes() -> bool {
    true
}

impl Default for ProjectionRequest {
    fn default() -> Self {
        Self {
            v_des: None,
            base_twist: None,
            joints: BTreeMap::new(),
            fill: Fill::Constraints,
            mode: Mode::Auto,
            lower: None,
            upper: None,
            velocity_limits: true,
            accel_limit: None,
            a: vec![],
            b: vec![],
            period: 0.0,
        }
    }
}

/// Number of base velocity coordinates (0 fixed, 3 planar, 6 floating); they come first.
pub fn base_dofs(model: &Model) -> usize {
    model.base.nv()
}

/// Index of a velocity coordinate by name or base alias.
pub fn coordinate_index(model: &Model, name: &str) -> Result<usize> {
    if let Ok(i) = model.v_index(name) {
        return Ok(i);
    }
    let alias: &[&str] = match model.base {
        BaseType::Fixed => &[],
        BaseType::Planar => &["vx", "vy", "wz"],
        BaseType::Floating => &["vx", "vy", "vz", "wx", "wy", "wz"],
    };
    alias.iter().position(|a| *a == name).ok_or_else(|| {
        Error::Invalid(format!(
            "unknown velocity coordinate '{name}' (known: {}{}{})",
            model.v_names.join(", "),
            if alias.is_empty() {
                ""
            } else {
                "; base aliases: "
            },
            alias.join(", ")
        ))
    })
}

fn finite(what: &str, x: f64) -> Result<f64> {
    check_finite(what, &[x]).map(|_| x)
}

/// Values per coordinate (`none` where not given).
fn per_coordinate(model: &Model, what: &str, spec: &PerCoordinate, none: f64) -> Result<Vec<f64>> {
    let nv = model.nv;
    let mut out = vec![none; nv];
    match spec {
        PerCoordinate::Named(map) => {
            for (name, value) in map {
                let i = coordinate_index(model, name)
                    .map_err(|e| Error::Invalid(format!("{what}: {e}")))?;
                if let Some(x) = value {
                    out[i] = *x;
                }
            }
        }
        PerCoordinate::Dense(values) => {
            if values.len() != nv {
                return Err(Error::Dimension {
                    what: what.into(),
                    expected: nv,
                    got: values.len(),
                });
            }
            for (o, x) in out.iter_mut().zip(values) {
                if let Some(x) = x {
                    *o = *x;
                }
            }
        }
    }
    if let Some(i) = out.iter().position(|x| x.is_nan()) {
        return Err(Error::NonFinite {
            what: format!("{what} ({})", model.v_names[i]),
            index: i,
            value: f64::NAN,
        });
    }
    Ok(out)
}

impl ProjectionRequest {
    /// Parse JSON, refusing unknown keys.
    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text).map_err(|e| Error::Invalid(format!("projection request: {e}")))
    }

    /// The problem in coordinate order. `j` is J(q) (nc × nv, for [`Fill::Constraints`]);
    /// `v_current` the state's velocity (for the acceleration limit).
    pub fn resolve(
        &self,
        model: &Model,
        j: &DMatrix<f64>,
        v_current: &[f64],
    ) -> Result<ProjectionProblem> {
        let nv = model.nv;
        let mut p = ProjectionProblem::new(model);
        p.velocity_limits = self.velocity_limits;
        p.v_des = self.desired(model, j)?;
        if let Some(lo) = &self.lower {
            p.lower = per_coordinate(model, "lower", lo, f64::NEG_INFINITY)?;
        }
        if let Some(hi) = &self.upper {
            p.upper = per_coordinate(model, "upper", hi, f64::INFINITY)?;
        }
        if let Some(al) = &self.accel_limit {
            p.accel_limit = Some(AccelLimit {
                dt: al.dt,
                a_max: per_coordinate(model, "accel_limit.a_max", &al.a_max, f64::INFINITY)?,
                v_current: al.v_current.clone().unwrap_or_else(|| v_current.to_vec()),
            });
        }
        if self.a.len() != self.b.len() {
            return Err(Error::Dimension {
                what: "b (one entry per row of A)".into(),
                expected: self.a.len(),
                got: self.b.len(),
            });
        }
        p.a = DMatrix::zeros(self.a.len(), nv);
        for (k, row) in self.a.iter().enumerate() {
            match row {
                RowSpec::Dense(x) => {
                    if x.len() != nv {
                        return Err(Error::Dimension {
                            what: format!("A row {k}"),
                            expected: nv,
                            got: x.len(),
                        });
                    }
                    for c in 0..nv {
                        p.a[(k, c)] = x[c];
                    }
                }
                RowSpec::Named(map) => {
                    for (name, x) in map {
                        let c = coordinate_index(model, name)
                            .map_err(|e| Error::Invalid(format!("A row {k}: {e}")))?;
                        p.a[(k, c)] = *x;
                    }
                }
            }
        }
        p.b = self.b.clone();
        p.validate(nv)?;
        Ok(p)
    }

    /// The mode this request resolves to.
    pub fn effective_mode(&self) -> Mode {
        match self.mode {
            Mode::Auto if self.base_twist.is_some() => Mode::Twist,
            Mode::Auto => Mode::Mass,
            m => m,
        }
    }

    /// Which coordinates the request gives (all for `v_des`).
    pub fn given(&self, model: &Model) -> Result<Vec<bool>> {
        let mut given = vec![self.v_des.is_some(); model.nv];
        if self.base_twist.is_some() {
            given[..base_dofs(model)].fill(true);
        }
        for name in self.joints.keys() {
            given[coordinate_index(model, name)?] = true;
        }
        Ok(given)
    }

    /// v_des in coordinate order, completed per `fill`.
    fn desired(&self, model: &Model, j: &DMatrix<f64>) -> Result<Vec<f64>> {
        let nv = model.nv;
        if let Some(v) = &self.v_des {
            if self.base_twist.is_some() || !self.joints.is_empty() {
                return Err(Error::Invalid(
                    "projection request: give v_des, or base_twist and/or joints, not both".into(),
                ));
            }
            crate::error::check_len("v_des", v, nv)?;
            check_finite("v_des", v)?;
            return Ok(v.clone());
        }
        let mut u = vec![0.0; nv];
        let mut given = vec![false; nv];
        if let Some(tw) = &self.base_twist {
            check_finite("base_twist", tw)?;
            let nb = base_dofs(model);
            let vals: Vec<f64> = match (model.base, tw.len()) {
                (BaseType::Fixed, _) => {
                    return Err(Error::Invalid(
                        "base_twist given but the model has a fixed base".into(),
                    ));
                }
                (BaseType::Planar, 3) | (BaseType::Floating, 6) => tw.clone(),
                (BaseType::Planar, 6) => {
                    if tw[2] != 0.0 || tw[3] != 0.0 || tw[4] != 0.0 {
                        return Err(Error::Invalid(format!(
                            "base_twist: a planar base cannot move along z or roll/pitch \
                             (vz, wx, wy = {}, {}, {})",
                            tw[2], tw[3], tw[4]
                        )));
                    }
                    vec![tw[0], tw[1], tw[5]]
                }
                (_, n) => {
                    return Err(Error::Dimension {
                        what: "base_twist".into(),
                        expected: nb,
                        got: n,
                    });
                }
            };
            u[..nb].copy_from_slice(&vals);
            given[..nb].fill(true);
        }
        for (name, x) in &self.joints {
            let i = coordinate_index(model, name)
                .map_err(|e| Error::Invalid(format!("joints: {e}")))?;
            u[i] = finite(&format!("joints.{name}"), *x)?;
            given[i] = true;
        }
        if !given.iter().any(|&g| g) {
            return Err(Error::Invalid(
                "projection request: no desired velocity (give v_des, base_twist or joints)".into(),
            ));
        }
        let free: Vec<usize> = (0..nv).filter(|&i| !given[i]).collect();
        if self.fill == Fill::Constraints && j.nrows() > 0 && !free.is_empty() {
            // u_F = argmin ‖J_F u_F + J_S u_S‖, minimum norm.
            let jf = DMatrix::from_fn(j.nrows(), free.len(), |r, c| j[(r, free[c])]);
            let rhs = DVector::from_fn(j.nrows(), |r, _| {
                -(0..nv)
                    .filter(|&c| given[c])
                    .map(|c| j[(r, c)] * u[c])
                    .sum::<f64>()
            });
            let svd = jf.svd(true, true);
            let smax = svd.singular_values.amax();
            if smax > 0.0 {
                let x = svd
                    .solve(&rhs, 1e-12 * smax)
                    .map_err(|e| Error::Invalid(format!("fill by constraints: {e}")))?;
                for (k, &i) in free.iter().enumerate() {
                    u[i] = x[k];
                }
            }
        }
        Ok(u)
    }
}
