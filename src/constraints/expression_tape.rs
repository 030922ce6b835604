//! A parsed expression as a flat postfix tape: evaluation and the gradient with respect to every
//! symbol in one reverse-mode sweep, both on fixed-size buffers in the stack frame (the tape is
//! at most `MAX_TAPE` long, one entry per token at most), so the hot path never allocates.

/// Functions of the syntax (the tape's [`Func`]s but the unary minus).
pub const FUNCTIONS: [&str; 7] = ["sqrt", "sin", "cos", "tan", "exp", "ln", "abs"];
/// Most distinct symbols one expression may use (values live in a stack buffer).
pub const MAX_SYMBOLS: usize = 16;
/// Most tokens one expression may have: it bounds the tape, whose evaluation buffers live on
/// the stack (about 8 KiB for the gradient). 400 tokens are 50 terms like `3*vx*vz^2 +`.
pub const MAX_TOKENS: usize = 400;

/// Longest tape: every token adds at most one entry (parentheses and a `+` sign add none).
pub(super) const MAX_TAPE: usize = MAX_TOKENS;
/// Tapes up to this long are evaluated on buffers of this size.
const SHORT: usize = 48;

/// A function of the syntax.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Func {
    Sqrt,
    Sin,
    Cos,
    Tan,
    Exp,
    Ln,
    Abs,
    /// The unary minus.
    Neg,
}

impl Func {
    /// The function named `name` in the scene syntax (`FUNCTIONS`).
    pub(super) fn named(name: &str) -> Option<Func> {
        Some(match name {
            "sqrt" => Func::Sqrt,
            "sin" => Func::Sin,
            "cos" => Func::Cos,
            "tan" => Func::Tan,
            "exp" => Func::Exp,
            "ln" => Func::Ln,
            "abs" => Func::Abs,
            _ => return None,
        })
    }

    fn apply(self, x: f64) -> f64 {
        match self {
            Func::Sqrt => x.sqrt(),
            Func::Sin => x.sin(),
            Func::Cos => x.cos(),
            Func::Tan => x.tan(),
            Func::Exp => x.exp(),
            Func::Ln => x.ln(),
            Func::Abs => x.abs(),
            Func::Neg => -x,
        }
    }

    /// The derivative at `x`, given the value `y` = self(x) already computed.
    fn derivative(self, x: f64, y: f64) -> f64 {
        match self {
            Func::Sqrt => 0.5 / y,
            Func::Sin => x.cos(),
            Func::Cos => -x.sin(),
            Func::Tan => 1.0 + y * y,
            Func::Exp => y,
            Func::Ln => 1.0 / x,
            // The subgradient 0 at the kink (sign(x), not NaN): `abs(v)` in a constraint is
            // usually evaluated exactly at v = 0, where any value in [−1, 1] is a valid
            // choice and 0 keeps the row finite and symmetric.
            Func::Abs if x == 0.0 => 0.0,
            Func::Abs => x.signum(),
            Func::Neg => -1.0,
        }
    }
}

/// A binary operator of the syntax.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Bin {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
}

impl Bin {
    fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            Bin::Add => a + b,
            Bin::Sub => a - b,
            Bin::Mul => a * b,
            Bin::Div => a / b,
            Bin::Pow => a.powf(b),
        }
    }
}

/// One tape entry: postfix, so an operator's operands are the entries just before it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Op {
    Const(f64),
    /// The value of symbol k (index into the values buffer).
    Sym(usize),
    Unary(Func),
    Binary(Bin),
}

/// The compiled expression.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Tape {
    pub(super) ops: Vec<Op>,
}

impl Tape {
    /// Append an operand.
    pub(super) fn push(&mut self, op: Op) {
        self.ops.push(op);
    }

    /// Append a unary function of the last operand; a constant operand is folded, so that an
    /// exponent like `-1` or `1/2` is a constant on the tape (see `gradient`, `Bin::Pow`).
    pub(super) fn push_unary(&mut self, f: Func) {
        match self.ops.last_mut() {
            Some(Op::Const(c)) => *c = f.apply(*c),
            _ => self.ops.push(Op::Unary(f)),
        }
    }

    /// Append a binary operator of the last two operands, folded when both are constants (a
    /// constant right operand is one entry, so the entry before it ends the left operand).
    pub(super) fn push_binary(&mut self, b: Bin) {
        let n = self.ops.len();
        if n >= 2
            && let (Op::Const(x), Op::Const(y)) = (self.ops[n - 2], self.ops[n - 1])
        {
            self.ops.truncate(n - 1);
            self.ops[n - 2] = Op::Const(b.apply(x, y));
            return;
        }
        self.ops.push(Op::Binary(b));
    }

    /// Map every symbol index k to `map[k]` (the parser numbers symbols as they appear).
    pub(super) fn renumber(&mut self, map: &[usize]) {
        for op in &mut self.ops {
            if let Op::Sym(k) = op {
                *k = map[*k];
            }
        }
    }

    /// The value at the symbols' values `vals`.
    pub(super) fn eval(&self, vals: &[f64]) -> f64 {
        // Most scene expressions are short: a small buffer spares zeroing the largest one.
        if self.ops.len() <= SHORT {
            self.eval_in::<SHORT>(vals)
        } else {
            self.eval_in::<MAX_TAPE>(vals)
        }
    }

    /// The value, and ∂/∂(symbol k) into `grad[k]` for every k < `vals.len()`.
    pub(super) fn gradient(&self, vals: &[f64], grad: &mut [f64]) -> f64 {
        if self.ops.len() <= SHORT {
            self.gradient_in::<SHORT>(vals, grad)
        } else {
            self.gradient_in::<MAX_TAPE>(vals, grad)
        }
    }

    /// `eval` with buffers of N ≥ the tape's length.
    fn eval_in<const N: usize>(&self, vals: &[f64]) -> f64 {
        let mut stack = [0.0f64; N];
        let mut sp = 0;
        for op in &self.ops {
            match *op {
                Op::Const(c) => {
                    stack[sp] = c;
                    sp += 1;
                }
                Op::Sym(k) => {
                    stack[sp] = vals[k];
                    sp += 1;
                }
                Op::Unary(f) => stack[sp - 1] = f.apply(stack[sp - 1]),
                Op::Binary(b) => {
                    sp -= 1;
                    stack[sp - 1] = b.apply(stack[sp - 1], stack[sp]);
                }
            }
        }
        stack[0]
    }

    /// `gradient` with buffers of N ≥ the tape's length: a forward pass keeps each entry's
    /// value and operands, then the adjoints flow back once. Non-finite partials (√ at 0, ln
    /// of 0) come out as they are; the caller checks finiteness.
    fn gradient_in<const N: usize>(&self, vals: &[f64], grad: &mut [f64]) -> f64 {
        let n = self.ops.len();
        let mut value = [0.0f64; N];
        let mut args = [(0u16, 0u16); N];
        let mut stack = [0u16; N];
        let mut sp = 0;
        for (i, op) in self.ops.iter().enumerate() {
            value[i] = match *op {
                Op::Const(c) => c,
                Op::Sym(k) => vals[k],
                Op::Unary(f) => {
                    sp -= 1;
                    let a = stack[sp];
                    args[i] = (a, a);
                    f.apply(value[a as usize])
                }
                Op::Binary(b) => {
                    sp -= 2;
                    let (a, c) = (stack[sp], stack[sp + 1]);
                    args[i] = (a, c);
                    b.apply(value[a as usize], value[c as usize])
                }
            };
            // MAX_TAPE ≤ u16::MAX (checked below), so the index fits.
            stack[sp] = i as u16;
            sp += 1;
        }
        grad[..vals.len()].fill(0.0);
        let mut adj = [0.0f64; N];
        adj[n - 1] = 1.0;
        for i in (0..n).rev() {
            let g = adj[i];
            let (a, c) = (args[i].0 as usize, args[i].1 as usize);
            match self.ops[i] {
                Op::Const(_) => {}
                Op::Sym(k) => grad[k] += g,
                Op::Unary(f) => adj[a] += g * f.derivative(value[a], value[i]),
                Op::Binary(b) => {
                    let (x, y) = (value[a], value[c]);
                    match b {
                        Bin::Add => {
                            adj[a] += g;
                            adj[c] += g;
                        }
                        Bin::Sub => {
                            adj[a] += g;
                            adj[c] -= g;
                        }
                        Bin::Mul => {
                            adj[a] += g * y;
                            adj[c] += g * x;
                        }
                        Bin::Div => {
                            adj[a] += g / y;
                            adj[c] -= g * value[i] / y;
                        }
                        Bin::Pow => {
                            // x^0 is the constant 1 (0·x^(−1) would be NaN at x = 0).
                            if y != 0.0 {
                                adj[a] += g * y * x.powf(y - 1.0);
                            }
                            // A constant exponent has no adjoint to receive x^y ln x, which
                            // is NaN for x < 0 and would make (−2)^2 look undefined. Where
                            // x^y = 0 (x = 0, y > 0) it is 0 identically in y.
                            if !matches!(self.ops[c], Op::Const(_)) && value[i] != 0.0 {
                                adj[c] += g * value[i] * x.ln();
                            }
                        }
                    }
                }
            }
        }
        value[n - 1]
    }
}

const _: () = assert!(MAX_TAPE <= u16::MAX as usize);
