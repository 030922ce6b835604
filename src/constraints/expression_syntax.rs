//! The scene syntax of `velocity` expressions: a tokenizer and a recursive-descent parser that
//! compiles straight to the postfix tape, naming every fault by its 1-based column.
//!
//!   expr  := term (('+' | '-') term)*          left-associative: a-b-c = (a-b)-c
//!   term  := unary (('*' | '/') unary)*        a/b*c = (a/b)*c, a/b/c = (a/b)/c
//!   unary := ('-' | '+') unary | power         -x^2 = -(x^2)
//!   power := atom ('^' unary)?                 right-associative: 2^3^2 = 2^9, 2^-1 = 0.5
//!   atom  := number | pi | t | symbol | FUNC '(' expr ')' | '(' expr ')'

use super::expression_tape::{Bin, FUNCTIONS, Func, MAX_SYMBOLS, MAX_TOKENS, Op, Tape};
use crate::error::ExpressionProblem;

/// Deepest nesting of parentheses, signs and exponents: the parser recurses once per level, so
/// this bounds its stack whatever the text.
pub(super) const MAX_DEPTH: usize = 64;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Tok<'a> {
    Num(f64),
    Ident(&'a str),
    Op(char),
    Open,
    Close,
}

fn syntax(column: usize, message: impl Into<String>) -> ExpressionProblem {
    ExpressionProblem::Syntax {
        column,
        message: message.into(),
    }
}

/// Length in bytes of the number at the start of `s` (ASCII), if one starts there:
/// `digits [. digits?] | . digits`, then optionally `e|E [+|-] digits`.
fn number_len(s: &[u8]) -> Option<usize> {
    let digits = |from: usize| s[from..].iter().take_while(|c| c.is_ascii_digit()).count();
    let mut n = digits(0);
    if s.get(n) == Some(&b'.') {
        let frac = digits(n + 1);
        if n == 0 && frac == 0 {
            return None;
        }
        n += 1 + frac;
    } else if n == 0 {
        return None;
    }
    if matches!(s.get(n), Some(b'e' | b'E')) {
        let sign = usize::from(matches!(s.get(n + 1), Some(b'+' | b'-')));
        let exp = digits(n + 1 + sign);
        // `2e` or `2e+` is a malformed number rather than 2 followed by a symbol `e`.
        if exp == 0 {
            return None;
        }
        n += 1 + sign + exp;
    }
    Some(n)
}

/// The tokens with their columns.
fn tokens(text: &str) -> Result<Vec<(usize, Tok<'_>)>, ExpressionProblem> {
    let mut out = vec![];
    let mut col = 1;
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        let len = if c.is_whitespace() {
            c.len_utf8()
        } else if c.is_ascii_digit() || c == '.' {
            let n = number_len(rest.as_bytes()).ok_or_else(|| syntax(col, "malformed number"))?;
            let x: f64 = rest[..n]
                .parse()
                .map_err(|_| syntax(col, "malformed number"))?;
            if !x.is_finite() {
                return Err(syntax(col, "number out of range"));
            }
            out.push((col, Tok::Num(x)));
            n
        } else if c.is_ascii_alphabetic() || c == '_' {
            let n = rest
                .find(|ch: char| !(ch.is_ascii_alphanumeric() || ch == '_'))
                .unwrap_or(rest.len());
            out.push((col, Tok::Ident(&rest[..n])));
            n
        } else {
            let tok = match c {
                '+' | '-' | '*' | '/' | '^' => Tok::Op(c),
                '(' => Tok::Open,
                ')' => Tok::Close,
                _ => return Err(syntax(col, format!("unexpected character '{c}'"))),
            };
            out.push((col, tok));
            1
        };
        // Every token and whitespace character is ASCII or one char, so columns count chars.
        col += rest[..len].chars().count();
        rest = &rest[len..];
    }
    Ok(out)
}

/// A compiled expression: the tape over its symbols, sorted by name.
#[derive(Debug)]
pub(super) struct Compiled {
    pub(super) tape: Tape,
    /// The symbols f uses (sorted by name), each with the column of its first use.
    pub(super) symbols: Vec<(String, usize)>,
}

/// Parse `text` (`known`: the declared symbols; `t` is always known) into a tape.
pub(super) fn compile(
    text: &str,
    known: impl Fn(&str) -> bool,
) -> Result<Compiled, ExpressionProblem> {
    let toks = tokens(text)?;
    if toks.len() > MAX_TOKENS {
        return Err(syntax(
            toks[MAX_TOKENS].0,
            format!("{} tokens, at most {MAX_TOKENS}", toks.len()),
        ));
    }
    let mut p = Parser {
        toks: &toks,
        pos: 0,
        end_col: text.chars().count() + 1,
        depth: 0,
        open: vec![],
        known: &known,
        symbols: vec![],
        tape: Tape::default(),
    };
    p.expr()?;
    if let Some(&(col, tok)) = p.toks.get(p.pos) {
        return Err(match tok {
            Tok::Close => syntax(col, "')' without a matching '('"),
            _ => syntax(col, "missing operator before this operand"),
        });
    }
    if p.symbols.len() > MAX_SYMBOLS {
        return Err(syntax(
            p.symbols[MAX_SYMBOLS].1,
            format!("{} symbols, at most {MAX_SYMBOLS}", p.symbols.len()),
        ));
    }
    let mut order: Vec<usize> = (0..p.symbols.len()).collect();
    order.sort_by(|&a, &b| p.symbols[a].0.cmp(p.symbols[b].0));
    let mut map = vec![0; order.len()];
    for (sorted, &k) in order.iter().enumerate() {
        map[k] = sorted;
    }
    let mut tape = p.tape;
    tape.renumber(&map);
    let symbols = order
        .iter()
        .map(|&k| (p.symbols[k].0.to_string(), p.symbols[k].1))
        .collect();
    Ok(Compiled { tape, symbols })
}

struct Parser<'t, 'a, K> {
    toks: &'t [(usize, Tok<'a>)],
    pos: usize,
    end_col: usize,
    depth: usize,
    /// Columns of the parentheses open at this point (the innermost is named if never closed).
    open: Vec<usize>,
    known: &'t K,
    /// Symbols in order of first appearance, with that column.
    symbols: Vec<(&'a str, usize)>,
    tape: Tape,
}

impl<'a, K: Fn(&str) -> bool> Parser<'_, 'a, K> {
    fn peek(&self) -> Option<(usize, Tok<'a>)> {
        self.toks.get(self.pos).copied()
    }

    fn peek_op(&self) -> Option<char> {
        match self.toks.get(self.pos) {
            Some(&(_, Tok::Op(c))) => Some(c),
            _ => None,
        }
    }

    /// One level deeper (a parenthesis, a sign or an exponent) at column `col`.
    fn enter(&mut self, col: usize) -> Result<(), ExpressionProblem> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(syntax(
                col,
                format!("nested deeper than {MAX_DEPTH} levels"),
            ));
        }
        Ok(())
    }

    fn expr(&mut self) -> Result<(), ExpressionProblem> {
        self.term()?;
        while let Some(c @ ('+' | '-')) = self.peek_op() {
            self.pos += 1;
            self.term()?;
            self.tape
                .push_binary(if c == '+' { Bin::Add } else { Bin::Sub });
        }
        Ok(())
    }

    fn term(&mut self) -> Result<(), ExpressionProblem> {
        self.unary()?;
        while let Some(c @ ('*' | '/')) = self.peek_op() {
            self.pos += 1;
            self.unary()?;
            self.tape
                .push_binary(if c == '*' { Bin::Mul } else { Bin::Div });
        }
        Ok(())
    }

    fn unary(&mut self) -> Result<(), ExpressionProblem> {
        match self.peek() {
            Some((col, Tok::Op(c @ ('+' | '-')))) => {
                self.enter(col)?;
                self.pos += 1;
                self.unary()?;
                if c == '-' {
                    self.tape.push_unary(Func::Neg);
                }
                self.depth -= 1;
                Ok(())
            }
            _ => self.power(),
        }
    }

    fn power(&mut self) -> Result<(), ExpressionProblem> {
        self.atom()?;
        if let Some((col, Tok::Op('^'))) = self.peek() {
            self.enter(col)?;
            self.pos += 1;
            self.unary()?;
            self.tape.push_binary(Bin::Pow);
            self.depth -= 1;
        }
        Ok(())
    }

    /// `( expr )` after the '(' at `self.pos`, which must be there.
    fn group(&mut self) -> Result<(), ExpressionProblem> {
        let (col, _) = self.toks[self.pos];
        self.enter(col)?;
        self.open.push(col);
        self.pos += 1;
        self.expr()?;
        match self.peek() {
            Some((_, Tok::Close)) => self.pos += 1,
            None => return Err(syntax(col, "'(' is never closed")),
            Some((c, _)) => return Err(syntax(c, "missing operator before this operand")),
        }
        self.open.pop();
        self.depth -= 1;
        Ok(())
    }

    fn atom(&mut self) -> Result<(), ExpressionProblem> {
        let Some((col, tok)) = self.peek() else {
            return Err(match (self.open.last(), self.toks.is_empty()) {
                (Some(&open), _) => syntax(open, "'(' is never closed"),
                (None, true) => syntax(1, "empty expression"),
                (None, false) => syntax(self.end_col, "the expression ends after an operator"),
            });
        };
        match tok {
            Tok::Num(x) => {
                self.pos += 1;
                self.tape.push(Op::Const(x));
            }
            Tok::Open => self.group()?,
            Tok::Close => return Err(syntax(col, "missing operand before ')'")),
            Tok::Op(c) => return Err(syntax(col, format!("'{c}' needs an operand on its left"))),
            Tok::Ident("pi") => {
                self.pos += 1;
                self.tape.push(Op::Const(std::f64::consts::PI));
            }
            Tok::Ident(name) => {
                let call = matches!(self.toks.get(self.pos + 1), Some((_, Tok::Open)));
                if let Some(f) = Func::named(name) {
                    if !call {
                        return Err(syntax(col, format!("function '{name}' needs ( … )")));
                    }
                    self.pos += 1;
                    self.group()?;
                    self.tape.push_unary(f);
                } else if name == "t" || (self.known)(name) {
                    self.pos += 1;
                    let k = match self.symbols.iter().position(|(s, _)| *s == name) {
                        Some(k) => k,
                        None => {
                            self.symbols.push((name, col));
                            self.symbols.len() - 1
                        }
                    };
                    self.tape.push(Op::Sym(k));
                } else if call {
                    return Err(syntax(
                        col,
                        format!(
                            "unknown function '{name}' (functions: {})",
                            FUNCTIONS.join(", ")
                        ),
                    ));
                } else {
                    return Err(ExpressionProblem::UnknownSymbol {
                        symbol: name.to_string(),
                        column: col,
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fault(text: &str) -> (usize, String) {
        match compile(text, |s| ["vx", "vy", "x"].contains(&s)) {
            Err(ExpressionProblem::Syntax { column, message }) => (column, message),
            Err(ExpressionProblem::UnknownSymbol { column, symbol }) => (column, symbol),
            Err(other) => panic!("{text}: {other:?}"),
            Ok(_) => panic!("{text}: accepted"),
        }
    }

    fn col(text: &str) -> usize {
        fault(text).0
    }

    #[test]
    fn faults_are_located() {
        // Unbalanced parentheses: the '(' never closed, the ')' never opened.
        assert_eq!(
            fault("vx - 0.5*sqrt(vx^2 + vy^2"),
            (14, "'(' is never closed".into())
        );
        assert_eq!(col("vx*((vy + 1)"), 4);
        assert_eq!(col("vx)"), 3);
        assert_eq!(col("(vx))"), 5);
        // Missing operand: an operator where an operand belongs, `()`.
        assert_eq!(
            fault("vx - * vy"),
            (6, "'*' needs an operand on its left".into())
        );
        assert_eq!(col("vx*()"), 5);
        assert_eq!(col("^vx"), 1);
        // Missing operator between operands.
        assert_eq!(col("vx vy"), 4);
        assert_eq!(col("(vx vy)"), 5);
        assert_eq!(col("2vx"), 2);
        // Unknown symbol, unknown function, a function without its parenthesis.
        assert_eq!(fault("vx + foo*vy"), (6, "foo".into()));
        let (c, m) = fault("vx + foo(vy)");
        assert_eq!(c, 6);
        assert!(m.starts_with("unknown function 'foo'"), "{m}");
        assert_eq!(col("sin x"), 1);
        // Trailing operator: the column after the end.
        assert_eq!(
            fault("vx +"),
            (5, "the expression ends after an operator".into())
        );
        assert_eq!(col("vx^"), 4);
        assert_eq!(col("vx + sin("), 9);
        // Characters and numbers.
        assert_eq!(col("vx # 2"), 4);
        assert_eq!(col("vx + 2e"), 6);
        assert_eq!(col("vx + ."), 6);
        assert_eq!(col("vx + 1e999"), 6);
        assert_eq!(col("θ + vx"), 1);
        assert_eq!(col("vx + θ"), 6);
        assert_eq!(fault(""), (1, "empty expression".into()));
        assert_eq!(fault("  "), (1, "empty expression".into()));
    }

    #[test]
    fn nesting_and_length_are_bounded() {
        // 64 levels of parentheses parse, the 65th '(' is named.
        let nest = |n: usize| format!("{}vx{}", "(".repeat(n), ")".repeat(n));
        assert!(compile(&nest(MAX_DEPTH), |s| s == "vx").is_ok());
        assert_eq!(
            fault(&nest(MAX_DEPTH + 1)),
            (65, "nested deeper than 64 levels".into())
        );
        // Signs and exponents nest too: 65 signs, the 65th at column 65.
        assert_eq!(col(&format!("{}vx", "-".repeat(65))), 65);
        // 400 tokens at most; an over-long text is named at its first token past the cap.
        let sum = |n: usize| vec!["vx"; n].join("+");
        assert!(compile(&sum(200), |s| s == "vx").is_ok()); // 399 tokens
        let (c, m) = fault(&format!("{}+vx", sum(200))); // 401 tokens
        assert_eq!(m, "401 tokens, at most 400");
        // Token 401 is the final `vx`: 200 `vx` and 200 `+` before it, 3·200 columns.
        assert_eq!(c, 601);
    }

    #[test]
    fn numbers_are_scanned() {
        let value = |text: &str| match compile(text, |_| false).unwrap().tape.ops[..] {
            [Op::Const(x)] => x,
            ref ops => panic!("{text}: {ops:?}"),
        };
        for (text, x) in [
            ("1", 1.0),
            ("1.5", 1.5),
            (".5", 0.5),
            ("1.", 1.0),
            ("2e-3", 0.002),
            ("1.5E+2", 150.0),
            ("7e2", 700.0),
            ("pi", std::f64::consts::PI),
        ] {
            assert_eq!(value(text), x, "{text}");
        }
    }

    #[test]
    fn symbols_are_sorted_by_name_with_their_first_column() {
        let c = compile("x*vy + vx - t*x", |s| ["vx", "vy", "x"].contains(&s)).unwrap();
        let names: Vec<(&str, usize)> = c.symbols.iter().map(|(s, k)| (s.as_str(), *k)).collect();
        assert_eq!(names, [("t", 13), ("vx", 8), ("vy", 3), ("x", 1)]);
    }
}
