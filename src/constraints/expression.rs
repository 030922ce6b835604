//! f(q, v, t) written in a scene: parsed by our own recursive-descent parser
//! (`expression_syntax.rs`) into a postfix tape (`expression_tape.rs`) that is evaluated and
//! differentiated (reverse mode, all symbols in one sweep) without allocation.
//!
//! Syntax: `+ - * / ^`, `sqrt sin cos tan exp ln abs`, decimal and scientific numbers, `pi`,
//! `t` for time [s], and the symbols declared under `variables:` (`q:NAME` or `v:NAME`, the
//! model's `q_names` / `v_names`, e.g. `v:root_joint:vx_local`), read the usual mathematical
//! way: `-x^2` is −(x²), `2^3^2` is 2⁹, `a/b*c` is (a/b)·c.
//!
//! Not exmex: its 0.21.0 evaluates `sqrt(vx^2 + vy^2 + 1)` as `vx^2 + sqrt(vy^2 + 1)`
//! (likewise `exp(a + b^2 + 2)`), with derivatives matching the misread f, so difference checks
//! cannot see it. A grammar of five rules is small enough to own
//! and test against closed forms, and it gives every syntax error a column.

use super::expression_syntax::compile;
use super::expression_tape::Tape;
use crate::error::ExpressionProblem;
use crate::model::Model;
use std::collections::BTreeMap;

pub use super::expression_tape::{FUNCTIONS, MAX_SYMBOLS};

/// Symbols with a fixed meaning: time [s] and π.
pub const RESERVED: [&str; 2] = ["t", "pi"];

/// What a symbol of the expression stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// Configuration coordinate `q[index]`; `body` carries its joint (for q̇ = G(q) v).
    Q {
        /// Index in q.
        index: usize,
        /// Body whose joint owns the coordinate.
        body: usize,
    },
    /// Velocity coordinate `v[index]`.
    V {
        /// Index in v.
        index: usize,
    },
    /// Time t [s].
    Time,
}

/// A parsed f(q, v, t), compiled for evaluation and its gradient.
#[derive(Clone, Debug)]
pub struct Expression {
    /// The text as written in the scene.
    pub text: String,
    /// f as a postfix tape over the symbols' indices in `symbols`.
    tape: Tape,
    /// The symbols f uses (sorted by name) with what they stand for.
    pub symbols: Vec<(String, Source)>,
}

impl Expression {
    /// Parse `text` with `variables` (symbol → `q:NAME` | `v:NAME`) against the model.
    pub fn parse(
        model: &Model,
        text: &str,
        variables: &BTreeMap<String, String>,
    ) -> Result<Expression, ExpressionProblem> {
        let mut sources = BTreeMap::new();
        for (sym, coord) in variables {
            sources.insert(sym.as_str(), variable_source(model, sym, coord)?);
        }
        let compiled = compile(text, |s| sources.contains_key(s))?;
        // `compile` accepts only `t` and the declared symbols, so every lookup succeeds.
        let symbols: Vec<(String, Source)> = compiled
            .symbols
            .into_iter()
            .map(|(name, _)| {
                let src = if name == "t" {
                    Source::Time
                } else {
                    sources[name.as_str()]
                };
                (name, src)
            })
            .collect();
        if !symbols.iter().any(|(_, s)| matches!(s, Source::V { .. })) {
            return Err(ExpressionProblem::Holonomic);
        }
        Ok(Expression {
            text: text.to_string(),
            tape: compiled.tape,
            symbols,
        })
    }

    /// Number of symbols (the length of a value buffer).
    pub fn len(&self) -> usize {
        self.symbols.len()
    }

    /// True when f uses no symbol (never: parsing refuses it).
    pub fn is_empty(&self) -> bool {
        self.symbols.is_empty()
    }

    /// The symbols' values at (q, v, t) into `vals[..len]`.
    pub fn values(&self, q: &[f64], v: &[f64], t: f64, vals: &mut [f64; MAX_SYMBOLS]) {
        for (k, (_, src)) in self.symbols.iter().enumerate() {
            vals[k] = match *src {
                Source::Q { index, .. } => q[index],
                Source::V { index } => v[index],
                Source::Time => t,
            };
        }
    }

    /// f at the symbols' values (non-finite where f is undefined; the caller checks).
    pub fn f(&self, vals: &[f64; MAX_SYMBOLS]) -> f64 {
        self.tape.eval(&vals[..self.len()])
    }

    /// f, and ∂f/∂(symbol k) into `grad[k]` for every symbol, in one sweep.
    pub fn gradient(&self, vals: &[f64; MAX_SYMBOLS], grad: &mut [f64; MAX_SYMBOLS]) -> f64 {
        self.tape.gradient(&vals[..self.len()], grad)
    }

    /// ∂f/∂(symbol k) at the symbols' values (a whole gradient sweep: for several k, call
    /// `gradient` once).
    pub fn df(&self, k: usize, vals: &[f64; MAX_SYMBOLS]) -> f64 {
        let mut grad = [0.0; MAX_SYMBOLS];
        self.gradient(vals, &mut grad);
        grad[k]
    }

    /// The time derivative of a configuration symbol, q̇_i = (G(q) v)_i, without allocation.
    pub fn qdot(model: &Model, body: usize, index: usize, q: &[f64], v: &[f64]) -> f64 {
        let j = &model.bodies[body].joint;
        let (iq, iv, nq, nv) = (j.idx_q, j.idx_v, j.kind.nq(), j.kind.nv());
        let mut buf = [0.0; 7];
        j.kind
            .qdot(&q[iq..iq + nq], &v[iv..iv + nv], &mut buf[..nq]);
        buf[index - iq]
    }
}

fn variable_source(model: &Model, sym: &str, coord: &str) -> Result<Source, ExpressionProblem> {
    let bad = |message: String| ExpressionProblem::BadVariable {
        symbol: sym.to_string(),
        message,
    };
    let mut chars = sym.chars();
    let ident = chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !ident {
        return Err(bad(
            "a symbol is a letter or _ followed by letters, digits or _".into(),
        ));
    }
    if RESERVED.contains(&sym) || FUNCTIONS.contains(&sym) {
        return Err(bad(format!(
            "'{sym}' is reserved (t is time, pi is π, and the functions)"
        )));
    }
    let unknown = |coordinate: &str, known: &[String]| ExpressionProblem::UnknownCoordinate {
        symbol: sym.to_string(),
        coordinate: coordinate.to_string(),
        known: known.join(", "),
    };
    match coord.split_once(':') {
        Some(("q", name)) => {
            let index = model
                .q_names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| unknown(name, &model.q_names))?;
            let body = (1..model.nbodies())
                .find(|&b| {
                    let j = &model.bodies[b].joint;
                    j.kind.nq() > 0 && (j.idx_q..j.idx_q + j.kind.nq()).contains(&index)
                })
                .ok_or_else(|| unknown(name, &model.q_names))?;
            Ok(Source::Q { index, body })
        }
        Some(("v", name)) => {
            let index = model
                .v_names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| unknown(name, &model.v_names))?;
            Ok(Source::V { index })
        }
        _ => Err(bad(format!(
            "'{coord}' must be q:NAME or v:NAME (a q_names or v_names entry of the model)"
        ))),
    }
}
