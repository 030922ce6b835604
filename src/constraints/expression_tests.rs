//! The compiled expression against closed forms (values and gradients) and central differences;
//! the syntax errors are tested next to the parser (`expression_syntax.rs`).

use super::expression::MAX_SYMBOLS;
use super::expression_syntax::compile;
use crate::error::ExpressionProblem;

/// f and its gradient at `vals`, given in the order of `names` (sorted, as `compile` sorts; every
/// name must be used by f).
fn run(text: &str, names: &[&str], vals: &[f64]) -> (f64, Vec<f64>) {
    let c = compile(text, |s| names.contains(&s)).unwrap_or_else(|e| panic!("{text}: {e}"));
    let used: Vec<&str> = c.symbols.iter().map(|(s, _)| s.as_str()).collect();
    assert_eq!(used, names, "{text}");
    let mut grad = [f64::NAN; MAX_SYMBOLS];
    let f = c.tape.gradient(vals, &mut grad);
    // Evaluation and the gradient's forward pass are the same arithmetic.
    assert_eq!(f.to_bits(), c.tape.eval(vals).to_bits(), "{text}");
    (f, grad[..vals.len()].to_vec())
}

fn value(text: &str, names: &[&str], vals: &[f64]) -> f64 {
    run(text, names, vals).0
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

fn assert_rel(what: &str, got: &[f64], want: &[f64], tol: f64) {
    for (k, (&g, &w)) in got.iter().zip(want).enumerate() {
        assert!(
            rel(g, w) <= tol,
            "{what}[{k}]: {g} vs {w} (rel {:.1e})",
            rel(g, w)
        );
    }
}

/// exmex 0.21.0 reads this as `vx^2 + sqrt(vy^2 + 1)` (1.652 here instead of 1.591), with the
/// derivatives of the misread f: the expression parser must not.
#[test]
fn sqrt_of_a_sum_with_powers_is_not_misparsed() {
    let (vx, vy) = (0.3f64, -1.2f64);
    let s = (vx * vx + vy * vy + 1.0).sqrt();
    let (f, g) = run("sqrt(vx^2 + vy^2 + 1)", &["vx", "vy"], &[vx, vy]);
    assert_rel("sqrt f", &[f], &[s], 1e-15);
    assert_rel("sqrt ∇f", &g, &[vx / s, vy / s], 1e-15);
    assert!((f - (vx * vx + (vy * vy + 1.0).sqrt())).abs() > 0.06);
    // The other reported shapes: a function of a sum ending in a power and a constant.
    let (a, b) = (0.3f64, -1.2f64);
    let e = (a + b * b + 2.0).exp();
    let (f, g) = run("exp(a + b^2 + 2)", &["a", "b"], &[a, b]);
    assert_rel("exp f", &[f], &[e], 1e-15);
    assert_rel("exp ∇f", &g, &[e, 2.0 * b * e], 1e-15);
    let (f, g) = run("exp(a + b)", &["a", "b"], &[a, b]);
    assert_rel("exp(a + b)", &[f], &[(a + b).exp()], 1e-15);
    assert_rel("∇exp(a + b)", &g, &[(a + b).exp(), (a + b).exp()], 1e-15);
    let (f, g) = run("sqrt(a + b^2 + 1)", &["a", "b"], &[a, b]);
    let s = (a + b * b + 1.0).sqrt();
    assert_rel("sqrt(a + b^2 + 1)", &[f], &[s], 1e-15);
    assert_rel("∇sqrt(a + b^2 + 1)", &g, &[0.5 / s, b / s], 1e-15);
}

#[test]
fn functions_match_closed_forms() {
    let x = 0.7f64;
    let (f, g) = run("ln(1 + x^2)", &["x"], &[x]);
    assert_rel("ln(1 + x²)", &[f], &[(1.0 + x * x).ln()], 1e-15);
    assert_rel("d ln(1 + x²)", &g, &[2.0 * x / (1.0 + x * x)], 1e-15);
    // sin² + cos² = 1 and its derivative 0, within rounding (2 ulp, 1e-15 absolute).
    for x in [-2.1, -0.3, 0.0, 0.9, 3.7, 11.0] {
        let (f, g) = run("sin(x)^2 + cos(x)^2", &["x"], &[x]);
        assert!((f - 1.0).abs() <= 2.0 * f64::EPSILON, "{x}: {f}");
        assert!(g[0].abs() <= 1e-15, "{x}: {}", g[0]);
    }
    let (f, g) = run("tan(x)", &["x"], &[x]);
    assert_rel("tan", &[f], &[x.sin() / x.cos()], 1e-15);
    assert_rel("tan'", &g, &[1.0 / (x.cos() * x.cos())], 1e-15);
    let (vx, vy, th) = (0.8f64, -0.5f64, 1.1f64);
    let (f, g) = run(
        "vx*sin(th) - vy*cos(th)",
        &["th", "vx", "vy"],
        &[th, vx, vy],
    );
    assert_rel("knife f", &[f], &[0.8 * th.sin() + 0.5 * th.cos()], 1e-15);
    let dth = vx * th.cos() + vy * th.sin();
    assert_rel("knife ∇f", &g, &[dth, th.sin(), -th.cos()], 1e-15);
    let (f, g) = run("x/(1 + y)", &["x", "y"], &[3.0, 0.5]);
    assert_rel("quotient", &[f], &[2.0], 1e-15);
    assert_rel("∇quotient", &g, &[1.0 / 1.5, -3.0 / 2.25], 1e-15);
}

#[test]
fn abs_has_the_sign_as_derivative_and_zero_at_the_kink() {
    for (x, a, d) in [
        (-1.5, 1.5, -1.0),
        (2.0, 2.0, 1.0),
        (0.0, 0.0, 0.0),
        (-0.0, 0.0, 0.0),
    ] {
        let (f, g) = run("abs(x)", &["x"], &[x]);
        assert_eq!((f, g[0]), (a, d), "abs at {x}");
    }
    // Inside a product: d/dvx (abs(vx - 0.2)*3) at the kink is 0, not NaN (as a
    // `sqrt((X)^2)` rewrite of abs would give).
    let (f, g) = run("abs(vx - 0.2)*3", &["vx"], &[0.2]);
    assert_eq!((f, g[0]), (0.0, 0.0));
}

#[test]
fn powers_match_closed_forms() {
    // Both operands symbolic: ∂/∂x = y x^(y−1), ∂/∂y = x^y ln x.
    let (x, y) = (1.7f64, 2.3f64);
    let p = (y * x.ln()).exp();
    let (f, g) = run("x^y", &["x", "y"], &[x, y]);
    assert_rel("x^y", &[f], &[p], 1e-15);
    assert_rel("∇x^y", &g, &[y * p / x, p * x.ln()], 1e-15);
    // A constant exponent forms no ln x: a negative base differentiates.
    let (f, g) = run("x^2", &["x"], &[-2.0]);
    assert_eq!((f, g[0]), (4.0, -4.0));
    let (f, g) = run("x^(1/2) + x^-1", &["x"], &[4.0]);
    assert_eq!((f, g[0]), (2.25, 0.25 - 1.0 / 16.0));
    // x^0 is the constant 1, also at x = 0; 0^y (y > 0) is 0 for every y.
    assert_eq!(run("x^0", &["x"], &[0.0]), (1.0, vec![0.0]));
    assert_eq!(run("x^y", &["x", "y"], &[0.0, 2.5]), (0.0, vec![0.0, 0.0]));
    // A symbolic exponent over a negative base: x^y ln x does not exist.
    let (f, g) = run("x^y", &["x", "y"], &[-2.0, 2.0]);
    assert_eq!((f, g[0]), (4.0, -4.0));
    assert!(g[1].is_nan());
}

#[test]
fn precedence_and_associativity_are_the_usual_ones() {
    let none: [&str; 0] = [];
    let num = |text: &str| value(text, &none, &[]);
    assert_eq!(num("2^3^2"), 512.0);
    assert_eq!(num("(2^3)^2"), 64.0);
    assert_eq!(num("-2^2"), -4.0);
    assert_eq!(num("(-2)^2"), 4.0);
    assert_eq!(num("2^-1"), 0.5);
    assert_eq!(num("2*-3"), -6.0);
    assert_eq!(num("1 - -1"), 2.0);
    assert_eq!(num("+2 - +1"), 1.0);
    assert_eq!(num("1.5E+2 + 2e-3"), 150.002);
    assert_eq!(num("2*pi"), std::f64::consts::TAU);
    assert_eq!(num("1 + 2*3^2"), 19.0);
    let abc = ["a", "b", "c"];
    let at = |text: &str| value(text, &abc, &[3.0, 4.0, 5.0]);
    assert_eq!(at("a/b*c"), 3.75); // (3/4)·5, not 3/20
    assert_eq!(at("a/b/c"), 0.15); // (3/4)/5
    assert_eq!(at("a-b-c"), -6.0); // not 3 − (−1)
    assert_eq!(at("a - b + c"), 4.0);
    assert_eq!(at("-a^2 + b*c"), 11.0); // −9 + 20
    assert_eq!(at("a*b^c/a"), 1024.0);
    assert_eq!(at("c^a^0 + b"), 9.0); // c^(a^0) = c
    let (f, g) = run("-x^2", &["x"], &[3.0]);
    assert_eq!((f, g[0]), (-9.0, -6.0));
    // Time is a symbol like the others.
    assert_eq!(value("t*vx", &["t", "vx"], &[2.0, 0.5]), 1.0);
}

/// A deterministic spread of points in [−1, 1].
fn points(n: usize, dim: usize) -> Vec<Vec<f64>> {
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..n).map(|_| (0..dim).map(|_| next()).collect()).collect()
}

#[test]
fn gradients_match_central_differences() {
    let exprs = [
        "a*sin(b) - c*cos(a*b) + exp(-a^2)",
        "sqrt(a^2 + b^2 + 1)*ln(2 + c^2)",
        "tan(0.3*a)/(1.5 + sin(b)) - abs(c - 2)*a",
        "(a + 2)^(b/3) + c^3 - 2^a",
        "a/(b + 2)/(c + 3) - a*(b + 2)^-2 + -c^2",
        "exp(a + b^2 + 2) - ln(1 + a^2*c^2)",
        "-(a + 2)^2^b + sqrt(4 - b)*c",
    ];
    let names = ["a", "b", "c"];
    let h = 1e-6;
    let mut worst = 0.0f64;
    for text in exprs {
        for x in points(20, 3) {
            let (_, g) = run(text, &names, &x);
            for k in 0..3 {
                let at = |d: f64| {
                    let mut y = x.clone();
                    y[k] += d;
                    value(text, &names, &y)
                };
                let fd = (at(h) - at(-h)) / (2.0 * h);
                let err = (g[k] - fd).abs() / g[k].abs().max(1.0);
                worst = worst.max(err);
                assert!(
                    err <= 1e-8,
                    "{text} ∂/∂{} at {x:?}: {} vs {fd}",
                    names[k],
                    g[k]
                );
            }
        }
    }
    eprintln!("gradient vs central differences (h = 1e-6): worst {worst:.1e}");
}

#[test]
fn seventeen_symbols_are_named_at_the_seventeenth() {
    let names: Vec<String> = (0..17).map(|i| format!("s{i:02}")).collect();
    let text = names.join("+");
    match compile(&text, |s| s.starts_with('s')) {
        // s16 starts after 16 names of 3 characters and 16 `+`.
        Err(ExpressionProblem::Syntax { column, message }) => {
            assert_eq!((column, message.as_str()), (65, "17 symbols, at most 16"))
        }
        other => panic!("{other:?}"),
    }
    assert!(compile(&names[..16].join("+"), |s| s.starts_with('s')).is_ok());
}

/// Tapes longer than the short buffers (48 entries) take the full-size ones: both give the
/// closed form, at the boundary and past it.
#[test]
fn long_tapes_match_closed_forms() {
    let a = 0.3f64;
    // Σ_{i=1}^{n} (a + i)^2: 5 entries per term (a, i, Add, 2, Pow) and n − 1 Adds, so 47
    // entries at n = 8 and 53 at n = 9.
    for n in [8, 9, 40] {
        let text = (1..=n)
            .map(|i| format!("(a + {i})^2"))
            .collect::<Vec<_>>()
            .join(" + ");
        let c = compile(&text, |s| s == "a").unwrap();
        assert_eq!(c.tape.ops.len(), 6 * n - 1, "{n}");
        let (f, g) = run(&text, &["a"], &[a]);
        let f_cf: f64 = (1..=n).map(|i| (a + i as f64).powi(2)).sum();
        let g_cf: f64 = (1..=n).map(|i| 2.0 * (a + i as f64)).sum();
        assert_rel("Σ (a + i)²", &[f], &[f_cf], 1e-15);
        assert_rel("Σ 2(a + i)", &g, &[g_cf], 1e-15);
    }
}
