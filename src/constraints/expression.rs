//! f(q, v, t) written in a scene: parsed and differentiated symbolically by exmex, evaluated
//! without allocation.
//!
//! Syntax: `+ - * / ^`, `sqrt sin cos tan exp ln abs`, decimal and scientific numbers, `pi`,
//! `t` for time [s], and the symbols declared under `variables:` (`q:NAME` or `v:NAME`, the
//! model's `q_names` / `v_names`, e.g. `v:root_joint:vx_local`). A unary minus before a power
//! (`-x^2`) is refused: exmex binds the sign first, `(−x)²`, the opposite of the usual reading.
//!
//! exmex reports most syntax errors without a position; a small tokenizer runs first so that a
//! malformed expression is named with its column. It checks token order only; exmex parses.

use super::expression_syntax::{check_tokens, rewrite_abs};
use crate::error::ExpressionProblem;
use crate::model::Model;
use exmex::prelude::*;
use exmex::{BinOp, MakeOperators, MatchLiteral, Operator, literal_matcher_from_pattern};
use std::collections::BTreeMap;

// Exactly the operators the scene syntax promises (exmex's default set also has `e`, `E`,
// `PI`, … as constants, which would silently shadow a variable called `e`). `abs` is spelled
// `sqrt(x^2)` for exmex (it has no derivative rule for `abs`), see `rewrite_abs`.
exmex::ops_factory!(
    Ops,
    f64,
    Operator::make_bin(
        "+",
        BinOp {
            apply: |a, b| a + b,
            prio: 1,
            is_commutative: true
        }
    ),
    Operator::make_bin_unary(
        "-",
        BinOp {
            apply: |a, b| a - b,
            prio: 1,
            is_commutative: false
        },
        |a| -a
    ),
    Operator::make_bin(
        "*",
        BinOp {
            apply: |a, b| a * b,
            prio: 2,
            is_commutative: true
        }
    ),
    Operator::make_bin(
        "/",
        BinOp {
            apply: |a, b| a / b,
            prio: 3,
            is_commutative: false
        }
    ),
    Operator::make_bin(
        "^",
        BinOp {
            apply: |a: f64, b| a.powf(b),
            prio: 4,
            is_commutative: false
        }
    ),
    Operator::make_unary("sqrt", |a| a.sqrt()),
    Operator::make_unary("sin", |a| a.sin()),
    Operator::make_unary("cos", |a| a.cos()),
    Operator::make_unary("tan", |a| a.tan()),
    Operator::make_unary("exp", |a| a.exp()),
    Operator::make_unary("ln", |a| a.ln()),
    Operator::make_constant("pi", std::f64::consts::PI)
);
literal_matcher_from_pattern!(Number, r"^(([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?)");

type Ex = FlatEx<f64, Ops, Number>;

/// Functions of the syntax.
pub const FUNCTIONS: [&str; 7] = ["sqrt", "sin", "cos", "tan", "exp", "ln", "abs"];
/// Symbols with a fixed meaning: time [s] and π.
pub const RESERVED: [&str; 2] = ["t", "pi"];
/// Most distinct symbols one expression may use (values live in a stack buffer).
pub const MAX_SYMBOLS: usize = 16;
/// Most tokens one expression may have. exmex parses and differentiates recursively with
/// large frames: 20 terms like `3*vx*vz^2` overflowed a 2 MiB test thread, 160 needed 32 MiB
/// (measured at opt-level 3); parsing runs on its own 64 MiB thread, and 400 tokens (50
/// terms like `3*vx*vz^2 +`, 8 tokens each) stay well inside it.
pub const MAX_TOKENS: usize = 400;

/// exmex's parse and the partial derivatives, on a thread with a stack large enough for
/// `MAX_TOKENS` (once per scene load, not in the hot path).
fn parse_and_differentiate(text: String) -> Result<(Ex, Vec<Ex>), ExpressionProblem> {
    let work = move || -> Result<(Ex, Vec<Ex>), ExpressionProblem> {
        let f = Ex::parse(&text).map_err(|e| ExpressionProblem::Syntax {
            column: 1,
            message: e.msg().to_string(),
        })?;
        let names = f.var_names().to_vec();
        let df = (0..names.len())
            .map(|k| {
                f.clone()
                    .partial(k)
                    .map_err(|e| ExpressionProblem::Derivative {
                        symbol: names[k].clone(),
                        message: e.msg().to_string(),
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok((f, df))
    };
    let failed = |message: String| ExpressionProblem::Syntax { column: 1, message };
    std::thread::Builder::new()
        .name("expression-parse".into())
        .stack_size(64 << 20)
        .spawn(work)
        .map_err(|e| failed(format!("cannot start the parsing thread: {e}")))?
        .join()
        .map_err(|_| failed("the expression library panicked while parsing".into()))?
}

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

/// A parsed f(q, v, t) with its first partial derivatives.
#[derive(Clone, Debug)]
pub struct Expression {
    /// The text as written in the scene.
    pub text: String,
    /// Boxed: exmex keeps 32 nodes inline, which would make every `Constraint` that large.
    f: Box<Ex>,
    /// ∂f/∂(symbol k), in the order of `symbols`.
    df: Vec<Ex>,
    /// The symbols f uses (exmex's order: sorted by name) with what they stand for.
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
        let ntok = check_tokens(text, |s| sources.contains_key(s))?;
        if ntok > MAX_TOKENS {
            return Err(ExpressionProblem::Syntax {
                column: 1,
                message: format!("{ntok} tokens, at most {MAX_TOKENS}"),
            });
        }
        let (f, df) = parse_and_differentiate(rewrite_abs(text))?;
        let names = f.var_names().to_vec();
        if names.len() > MAX_SYMBOLS {
            return Err(ExpressionProblem::Syntax {
                column: 1,
                message: format!("{} symbols, at most {MAX_SYMBOLS}", names.len()),
            });
        }
        let mut symbols = Vec::with_capacity(names.len());
        for n in &names {
            let src = if n == "t" {
                Source::Time
            } else {
                *sources
                    .get(n.as_str())
                    .ok_or_else(|| ExpressionProblem::UnknownSymbol {
                        symbol: n.clone(),
                        column: column_of(text, n),
                    })?
            };
            symbols.push((n.clone(), src));
        }
        if !symbols.iter().any(|(_, s)| matches!(s, Source::V { .. })) {
            return Err(ExpressionProblem::Holonomic);
        }
        Ok(Expression {
            text: text.to_string(),
            f: Box::new(f),
            df,
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

    /// f at the symbols' values (NaN where exmex refuses, which it does only on a length
    /// mismatch; the caller checks finiteness).
    pub fn f(&self, vals: &[f64; MAX_SYMBOLS]) -> f64 {
        self.f.eval(&vals[..self.len()]).unwrap_or(f64::NAN)
    }

    /// ∂f/∂(symbol k) at the symbols' values.
    pub fn df(&self, k: usize, vals: &[f64; MAX_SYMBOLS]) -> f64 {
        self.df[k].eval(&vals[..self.len()]).unwrap_or(f64::NAN)
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

/// 1-based column of the first occurrence of identifier `sym` in `text` (1 if not found).
fn column_of(text: &str, sym: &str) -> usize {
    text.find(sym)
        .map(|b| text[..b].chars().count() + 1)
        .unwrap_or(1)
}
