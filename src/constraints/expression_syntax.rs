//! The scene syntax of `velocity` expressions ahead of exmex: a tokenizer that locates faults
//! by column (exmex's own messages carry no position) and the `abs` rewrite exmex can
//! differentiate. It checks token order only; exmex parses.

use super::expression::{FUNCTIONS, Number, RESERVED};
use crate::error::ExpressionProblem;
use exmex::MatchLiteral;

/// `abs(X)` → `sqrt((X)^2)`: the same function, with a derivative exmex knows (X/|X|; at
/// X = 0 it is not defined, and the NaN is caught as non-finite).
pub(super) fn rewrite_abs(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 16);
    let mut rest = text;
    while let Some(i) = find_word(rest, "abs") {
        out.push_str(&rest[..i]);
        let after = rest[i + 3..].trim_start();
        // check_tokens guaranteed `abs` is followed by a balanced `( … )`.
        let mut depth = 0usize;
        let mut end = 0;
        for (k, c) in after.char_indices() {
            match c {
                '(' => depth += 1,
                ')' => {
                    depth -= 1;
                    if depth == 0 {
                        end = k;
                        break;
                    }
                }
                _ => {}
            }
        }
        out.push_str("sqrt((");
        out.push_str(&rewrite_abs(&after[1..end]));
        out.push_str(")^2)");
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    out
}

/// Byte offset of `word` as a whole identifier in `s`.
fn find_word(s: &str, word: &str) -> Option<usize> {
    let is_id = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut from = 0;
    while let Some(i) = s[from..].find(word).map(|i| i + from) {
        let before = s[..i].chars().next_back().is_some_and(is_id);
        let after = s[i + word.len()..].chars().next().is_some_and(is_id);
        if !before && !after {
            return Some(i);
        }
        from = i + word.len();
    }
    None
}

#[derive(Clone, Copy, PartialEq)]
enum Tok<'a> {
    Num,
    Ident(&'a str),
    Op(char),
    Open,
    Close,
}

fn tokens(text: &str) -> Result<Vec<(usize, Tok<'_>)>, ExpressionProblem> {
    let mut out = vec![];
    let chars: Vec<(usize, char)> = text.char_indices().collect();
    let mut k = 0;
    while k < chars.len() {
        let (byte, c) = chars[k];
        let col = k + 1;
        if c.is_whitespace() {
            k += 1;
            continue;
        }
        let tok = if c.is_ascii_digit() || c == '.' {
            let m = Number::is_literal(&text[byte..]).ok_or_else(|| ExpressionProblem::Syntax {
                column: col,
                message: "malformed number".into(),
            })?;
            k += m.chars().count();
            Tok::Num
        } else if c.is_ascii_alphabetic() || c == '_' {
            let len = text[byte..]
                .find(|ch: char| !(ch.is_ascii_alphanumeric() || ch == '_'))
                .unwrap_or(text.len() - byte);
            k += text[byte..byte + len].chars().count();
            Tok::Ident(&text[byte..byte + len])
        } else {
            k += 1;
            match c {
                '+' | '-' | '*' | '/' | '^' => Tok::Op(c),
                '(' => Tok::Open,
                ')' => Tok::Close,
                _ => {
                    return Err(ExpressionProblem::Syntax {
                        column: col,
                        message: format!("unexpected character '{c}'"),
                    });
                }
            }
        };
        out.push((col, tok));
    }
    Ok(out)
}

/// Token order, parentheses, function calls and symbols, with the column of the first fault.
/// Returns the number of tokens.
pub(super) fn check_tokens(
    text: &str,
    known: impl Fn(&str) -> bool,
) -> Result<usize, ExpressionProblem> {
    let syntax = |column: usize, message: &str| ExpressionProblem::Syntax {
        column,
        message: message.to_string(),
    };
    let toks = tokens(text)?;
    let end_col = text.chars().count() + 1;
    if toks.is_empty() {
        return Err(syntax(1, "empty expression"));
    }
    let mut expect_operand = true;
    // Per open parenthesis: its column; per depth: whether the current operand was signed.
    let mut open: Vec<usize> = vec![];
    let mut signed: Vec<bool> = vec![false];
    let mut prev_unary = false;
    for (i, &(col, tok)) in toks.iter().enumerate() {
        let depth = open.len();
        let starts_operand = matches!(tok, Tok::Num | Tok::Ident(_) | Tok::Open);
        if starts_operand && !expect_operand {
            return Err(syntax(col, "missing operator before this operand"));
        }
        // A function's parenthesis continues the operand its name started (and its sign).
        let after_function =
            i > 0 && matches!(toks[i - 1].1, Tok::Ident(n) if FUNCTIONS.contains(&n));
        if starts_operand && !after_function {
            signed[depth] = prev_unary;
        }
        prev_unary = false;
        match tok {
            Tok::Num => expect_operand = false,
            Tok::Ident(name) => {
                if FUNCTIONS.contains(&name) {
                    if !matches!(toks.get(i + 1), Some((_, Tok::Open))) {
                        return Err(syntax(col, &format!("function '{name}' needs ( … )")));
                    }
                } else if RESERVED.contains(&name) || known(name) {
                    expect_operand = false;
                } else {
                    return Err(ExpressionProblem::UnknownSymbol {
                        symbol: name.to_string(),
                        column: col,
                    });
                }
            }
            Tok::Op('+' | '-') if expect_operand => prev_unary = true,
            Tok::Op(c) => {
                if expect_operand {
                    return Err(syntax(col, &format!("'{c}' needs an operand on its left")));
                }
                if c == '^' && signed[depth] {
                    return Err(syntax(
                        col,
                        "a sign before a power is ambiguous here (exmex reads -x^2 as (-x)^2): \
                         write -(x^2) or (-x)^2",
                    ));
                }
                expect_operand = true;
            }
            Tok::Open => {
                open.push(col);
                signed.push(false);
                expect_operand = true;
            }
            Tok::Close => {
                if open.is_empty() {
                    return Err(syntax(col, "')' without a matching '('"));
                }
                if expect_operand {
                    return Err(syntax(col, "missing operand before ')'"));
                }
                open.pop();
                signed.pop();
                expect_operand = false;
            }
        }
    }
    if let Some(&col) = open.last() {
        return Err(syntax(col, "'(' is never closed"));
    }
    if expect_operand {
        return Err(syntax(end_col, "the expression ends after an operator"));
    }
    Ok(toks.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn col(text: &str) -> usize {
        match check_tokens(text, |s| ["vx", "vy", "x"].contains(&s)) {
            Err(ExpressionProblem::Syntax { column, .. })
            | Err(ExpressionProblem::UnknownSymbol { column, .. }) => column,
            other => panic!("{text}: {other:?}"),
        }
    }

    #[test]
    fn faults_are_located() {
        assert_eq!(col("vx - 0.5*sqrt(vx^2 + vy^2"), 14);
        assert_eq!(col("vx - * vy"), 6);
        assert_eq!(col("vx vy"), 4);
        assert_eq!(col("vx + foo(vy)"), 6);
        assert_eq!(col("vx)"), 3);
        assert_eq!(col("vx +"), 5);
        assert_eq!(col("vx # 2"), 4);
        assert_eq!(col("-vx^2"), 4);
        assert_eq!(col("-sin(x)^2"), 8);
        assert_eq!(col("sin x"), 1);
        assert_eq!(col("vx*()"), 5);
        assert!(
            check_tokens("-(vx^2) + 2^-1*vy - 1.5e-3*x*t + pi", |s| s == "vx"
                || s == "vy"
                || s == "x")
            .is_ok()
        );
    }

    #[test]
    fn abs_is_rewritten_with_balanced_parentheses() {
        assert_eq!(rewrite_abs("abs(vx) + absx"), "sqrt((vx)^2) + absx");
        assert_eq!(
            rewrite_abs("2*abs((a+b)*abs(c))"),
            "2*sqrt(((a+b)*sqrt((c)^2))^2)"
        );
        // An identifier containing `abs` before the call: the search resumes after it and
        // finds the call at its own byte offset (7), not relative to where it resumed (3).
        assert_eq!(rewrite_abs("absx + abs(vx)"), "absx + sqrt((vx)^2)");
        assert_eq!(rewrite_abs("xabs*abs(vy)"), "xabs*sqrt((vy)^2)");
    }
}
