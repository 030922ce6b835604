//! A velocity constraint written as an expression, f(q, v, t) = 0, possibly nonlinear in v
//! (seed 001, eq. 1): a servo constraint, a speed governor, Appell–Hamel's ż = a√(ẋ² + ẏ²).
//!
//! Chetaev's virtual displacements (the seed's eq. 22, its scheme for constraints homogeneous
//! in the velocities): the constraint force is Jᵀλ with J = ∂f/∂v (1 × nv). Differentiating
//! f along the motion gives the acceleration row
//!   ∂f/∂v q̈ = −(∂f/∂q q̇ + ∂f/∂t),   q̇ = G(q) v,
//! so γ = ∂f/∂q q̇ + ∂f/∂t (q̈ is the time derivative of v, as everywhere in the project; on a
//! free-flyer or planar base a configuration symbol's q̇ is its entry of G(q) v, e.g. ẋ of
//! `q:root_joint:x` is the world-axis velocity, not `vx_local`). φ = 0 (nonholonomic), and the
//! velocity residual reported and fed to the Baumgarte term K_d is f itself, not J v: the two
//! agree only for f homogeneous of degree 1 in v (Euler), and f is what must vanish.
//! λ: [generalized force × v-unit / f-unit]; Jᵀλ is a generalized force [N or N·m] per v.
//!
//! `velocity_determined` (the seed's eqs. 5–6): the rows are the same (the motion still obeys
//! f differentiated), but the virtual displacements use B of eq. (6) for the dependent
//! velocity; the embedded form projects on them (`dynamics/embedded.rs`), the multiplier form
//! refuses such rows. docs/nonholonomic.md derives both.

use super::expression::{Expression, MAX_SYMBOLS, Source};
use super::{ConstraintRows, RowSink, VirtualDisplacements};
use crate::algorithm::Data;
use crate::error::{Error, ExpressionProblem, Result};
use crate::model::Model;
use std::collections::BTreeMap;

/// f(q, v, t) = 0 (one row): rows and force after Chetaev, or the seed's velocity-determined
/// virtual displacements in the embedded form.
#[derive(Clone, Debug)]
pub struct VelocityConstraint {
    /// The parsed expression with its partial derivatives.
    pub expression: Expression,
    /// Velocity index the scene asks to solve for in the embedded form (`dependent:`), if any.
    pub dependent: Option<usize>,
    /// `virtual_displacements: velocity_determined` (requires `dependent`).
    pub velocity_determined: bool,
    /// v⁽⁰⁾ of eq. (4) per velocity index (absent: 0).
    pub reference: Vec<(usize, f64)>,
}

/// 8-point Gauss–Legendre on [−1, 1]: the positive nodes and their weights (Abramowitz &
/// Stegun, table 25.4); exact for polynomials of degree ≤ 15.
const GAUSS8: [(f64, f64); 4] = [
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (0.960_289_856_497_536_2, 0.101_228_536_290_376_3),
];

impl VelocityConstraint {
    /// Validate a scene's declaration against the model.
    pub fn build(
        model: &Model,
        name: &str,
        text: &str,
        variables: &BTreeMap<String, String>,
        vd: VirtualDisplacements,
        dependent: &[String],
        reference: &BTreeMap<String, f64>,
    ) -> Result<VelocityConstraint> {
        let err = |problem| Error::Expression {
            name: name.into(),
            expression: text.into(),
            problem: Box::new(problem),
        };
        let dep_err = |message: String| err(ExpressionProblem::Dependent { message });
        let expression = Expression::parse(model, text, variables).map_err(err)?;
        let velocity_of = |sym: &str| {
            expression.symbols.iter().find_map(|(s, src)| match src {
                Source::V { index } if s == sym => Some(*index),
                _ => None,
            })
        };
        let dependent = match dependent {
            [] => None,
            [sym] => Some(velocity_of(sym).ok_or_else(|| {
                dep_err(format!(
                    "'{sym}' is not a velocity symbol of the expression"
                ))
            })?),
            _ => {
                return Err(dep_err(format!(
                    "{} symbols for one equation: name at most one",
                    dependent.len()
                )));
            }
        };
        let velocity_determined = vd == VirtualDisplacements::VelocityDetermined;
        if velocity_determined && dependent.is_none() {
            return Err(dep_err(
                "velocity_determined needs dependent: its B coefficients are derivatives of \
                 the solved dependent velocity (seed eqs. 2, 6)"
                    .into(),
            ));
        }
        if !reference.is_empty() && !velocity_determined {
            return Err(Error::Constraint {
                name: name.into(),
                message: "reference_velocity is used only with velocity_determined".into(),
            });
        }
        let mut refs = vec![];
        for (sym, &value) in reference {
            let index = velocity_of(sym).ok_or_else(|| Error::Constraint {
                name: name.into(),
                message: format!("reference_velocity: '{sym}' is not a velocity symbol of f"),
            })?;
            if !value.is_finite() {
                return Err(Error::Constraint {
                    name: name.into(),
                    message: format!("reference_velocity: '{sym}' is not finite"),
                });
            }
            refs.push((index, value));
        }
        Ok(VelocityConstraint {
            expression,
            dependent,
            velocity_determined,
            reference: refs,
        })
    }

    /// ∂f/∂v[index] from the symbols' gradient (several symbols may name one coordinate).
    fn df_dv(&self, index: usize, grad: &[f64; MAX_SYMBOLS]) -> f64 {
        let e = &self.expression;
        (0..e.len())
            .filter(|&k| e.symbols[k].1 == Source::V { index })
            .map(|k| grad[k])
            .sum()
    }

    /// The seed's velocity-determined coefficients, eq. (6) summed: with u(σ) = v⁽⁰⁾ + σ (v − v⁽⁰⁾)
    /// on the independent velocities α of f and q̂ the dependent velocity solved from f = 0,
    ///   B_α = Σ_l 1/(l+1)! ∂^{l+1}q̂/∂v_α∂v^l |_{v⁽⁰⁾} [v − v⁽⁰⁾]^l = ∫₀¹ ∂q̂/∂v_α(u(σ)) dσ,
    /// ∂q̂/∂v_α = −(∂f/∂v_α)/(∂f/∂v_d) (implicit functions), by 8-point Gauss–Legendre with
    /// q̂ at each node by Newton. Returns (velocity index α, B_α). Off the hot path (allocates).
    pub fn velocity_determined_b(
        &self,
        q: &[f64],
        v: &[f64],
        t: f64,
    ) -> std::result::Result<Vec<(usize, f64)>, String> {
        let d = self.dependent.ok_or("no dependent velocity")?;
        let mut alphas: Vec<usize> = self.velocity_indices().filter(|&i| i != d).collect();
        alphas.sort();
        alphas.dedup();
        let v0 = |i: usize| {
            self.reference
                .iter()
                .find(|(j, _)| *j == i)
                .map_or(0.0, |r| r.1)
        };
        let mut b = vec![0.0; alphas.len()];
        let mut u = v.to_vec();
        let mut vals = [0.0; MAX_SYMBOLS];
        let mut grad = [0.0; MAX_SYMBOLS];
        let nodes = GAUSS8
            .iter()
            .flat_map(|&(x, w)| [((1.0 - x) / 2.0, w / 2.0), ((1.0 + x) / 2.0, w / 2.0)]);
        for (sigma, w) in nodes {
            for &a in &alphas {
                u[a] = v0(a) + sigma * (v[a] - v0(a));
            }
            // q̂(u): Newton in v_d from the previous node's value.
            let mut done = false;
            for _ in 0..50 {
                self.expression.values(q, &u, t, &mut vals);
                let f = self.expression.gradient(&vals, &mut grad);
                let fd = self.df_dv(d, &grad);
                if !(f.is_finite() && fd.is_finite()) || fd == 0.0 {
                    return Err(format!("f or ∂f/∂v_d undefined at σ = {sigma:.3}"));
                }
                if f.abs() <= 1e-14 * u[d].abs().max(1.0) {
                    done = true;
                    break;
                }
                u[d] -= f / fd;
            }
            if !done {
                return Err(format!(
                    "no dependent velocity solves f = 0 at σ = {sigma:.3}"
                ));
            }
            let fd = self.df_dv(d, &grad);
            for (k, &a) in alphas.iter().enumerate() {
                b[k] -= w * self.df_dv(a, &grad) / fd;
            }
        }
        Ok(alphas.into_iter().zip(b).collect())
    }

    /// f at (q, v, t).
    pub fn residual(&self, q: &[f64], v: &[f64], t: f64) -> f64 {
        let mut vals = [0.0; MAX_SYMBOLS];
        self.expression.values(q, v, t, &mut vals);
        self.expression.f(&vals)
    }

    /// Velocity indices f depends on.
    pub fn velocity_indices(&self) -> impl Iterator<Item = usize> + '_ {
        self.expression.symbols.iter().filter_map(|(_, s)| match s {
            Source::V { index } => Some(*index),
            _ => None,
        })
    }
}

impl ConstraintRows for VelocityConstraint {
    fn dim(&self) -> usize {
        1
    }

    fn fill(&self, model: &Model, _data: &Data, out: &mut RowSink) {
        let e = &self.expression;
        let mut vals = [0.0; MAX_SYMBOLS];
        e.values(out.q, out.v, out.t, &mut vals);
        let r = out.row0;
        out.clear_row(0);
        let mut grad = [0.0; MAX_SYMBOLS];
        let f = e.gradient(&vals, &mut grad);
        let mut gamma = 0.0;
        for (&d, (_, src)) in grad.iter().zip(&e.symbols) {
            match *src {
                Source::V { index } => out.j[(r, index)] += d,
                Source::Q { index, body } => {
                    gamma += d * Expression::qdot(model, body, index, out.q, out.v)
                }
                Source::Time => gamma += d,
            }
        }
        out.finish(r, 0.0, gamma, false);
        out.jv[r] = f;
        out.residual_given[r] = true;
    }
}
