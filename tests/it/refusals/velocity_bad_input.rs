//! `kind: velocity` — malformed declarations give named errors (with the column of a syntax
//! fault), over-long expressions are refused by name, and states where the expression has no
//! derivative are errors, not NaN accelerations.

use crate::common;
use common::*;
use constraint_dynamics::error::ExpressionProblem;
use constraint_dynamics::{Error, Scene, System};

use crate::counting_alloc;
use counting_alloc::allocations;

// ---------------------------------------------------------------------------------------------
// Malformed declarations are named.
// ---------------------------------------------------------------------------------------------

fn problem(expression: &str, variables: &str, extra: &str) -> ExpressionProblem {
    let yaml = format!(
        "  - name: c\n    kind: velocity\n    expression: {expression:?}\n    variables: {variables}\n{extra}"
    );
    match scene_from("point_mass.urdf", "floating", &yaml) {
        Err(Error::Expression { name, problem, .. }) => {
            assert_eq!(name, "c");
            *problem
        }
        Err(e) => panic!("{expression}: another error: {e}"),
        Ok(_) => panic!("{expression}: accepted"),
    }
}

#[test]
fn malformed_expressions_are_named() {
    let vars = r#"{vx: "v:root_joint:vx_local", vz: "v:root_joint:vz_local", x: "q:root_joint:x"}"#;
    let syntax = |e: &str| match problem(e, vars, "") {
        ExpressionProblem::Syntax { column, .. } => column,
        p => panic!("{e}: {p}"),
    };
    assert_eq!(syntax("vz - 0.5*sqrt(vx^2 + x^2"), 14);
    assert_eq!(syntax("vz - * vx"), 6);
    assert_eq!(syntax("vz + 2 vx"), 8);
    assert_eq!(syntax("vz ? vx"), 4);
    assert_eq!(syntax(""), 1);
    assert_eq!(syntax("vz + sin(vx"), 9);
    assert_eq!(syntax("vz + vx^"), 9);
    assert_eq!(
        syntax(&format!("{}vz{}", "(".repeat(65), ")".repeat(65))),
        65
    );
    match problem("vz + foo(vx)", vars, "") {
        ExpressionProblem::Syntax { column, message } => {
            assert_eq!(column, 6);
            assert!(message.starts_with("unknown function 'foo'"), "{message}");
        }
        p => panic!("{p}"),
    }
    match problem("vz - foo*vx", vars, "") {
        ExpressionProblem::UnknownSymbol { symbol, column } => {
            assert_eq!((symbol.as_str(), column), ("foo", 6))
        }
        p => panic!("{p}"),
    }
    match problem(
        "vz - vx",
        r#"{vx: "v:root_joint:vx_local", vz: "v:root_joint:vz"}"#,
        "",
    ) {
        ExpressionProblem::UnknownCoordinate {
            symbol,
            coordinate,
            known,
        } => {
            assert_eq!(
                (symbol.as_str(), coordinate.as_str()),
                ("vz", "root_joint:vz")
            );
            assert!(known.contains("root_joint:vz_local"), "{known}");
        }
        p => panic!("{p}"),
    }
    match problem(
        "vz - vx",
        r#"{vx: "v:root_joint:vx_local", vz: "speed:root_joint:vz_local"}"#,
        "",
    ) {
        ExpressionProblem::BadVariable { symbol, .. } => assert_eq!(symbol, "vz"),
        p => panic!("{p}"),
    }
    match problem(
        "t - vx",
        r#"{vx: "v:root_joint:vx_local", t: "q:root_joint:z"}"#,
        "",
    ) {
        ExpressionProblem::BadVariable { symbol, message } => {
            assert_eq!(symbol, "t");
            assert!(message.contains("reserved"), "{message}");
        }
        p => panic!("{p}"),
    }
    // A symbol is an identifier: a letter or _, then letters, digits or _ (both halves of the
    // rule: a digit first, and a bad character after a good first letter).
    for bad in ["2vx", "v-x", "v x"] {
        let vars = format!(r#"{{vz: "v:root_joint:vz_local", "{bad}": "v:root_joint:vx_local"}}"#);
        match problem("vz", &vars, "") {
            ExpressionProblem::BadVariable { symbol, message } => {
                assert_eq!(symbol, bad);
                assert!(message.contains("letter or _ followed by"), "{message}");
            }
            p => panic!("{bad}: {p}"),
        }
    }
    let holonomic = problem("x^2 + sin(t) - 1", vars, "");
    assert_eq!(holonomic, ExpressionProblem::Holonomic);
    assert!(
        holonomic.to_string().contains("holonomic constraint"),
        "{holonomic}"
    );
    match problem("vz - vx", vars, "    dependent: [x]\n") {
        ExpressionProblem::Dependent { message } => assert!(message.contains("'x'"), "{message}"),
        p => panic!("{p}"),
    }
    match problem("vz - vx", vars, "    dependent: [vx, vz]\n") {
        ExpressionProblem::Dependent { .. } => {}
        p => panic!("{p}"),
    }
    // The error message names the constraint, the expression and the column.
    let e = scene_from(
        "point_mass.urdf",
        "floating",
        "  - name: lift\n    kind: velocity\n    expression: \"vz - (vx\"\n    variables: {vx: \"v:root_joint:vx_local\", vz: \"v:root_joint:vz_local\"}\n",
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        e.contains("constraint 'lift'") && e.contains("column 6"),
        "{e}"
    );
}

/// A derivative that does not exist at the state (√ at 0 in the denominator) is an error that
/// names the constraint, not a NaN acceleration.
#[test]
fn undefined_derivatives_are_errors_not_nans() {
    let sc = Scene::load(repo_dir().join("params/appell_hamel.yaml")).unwrap();
    let mut sys = System::from_scene(&sc).unwrap();
    let v = vec![0.0; 6];
    match sys.forward_dynamics(&sc.q0, &v, &[0.0; 6], true) {
        Err(Error::Constraint { name, message }) => {
            assert_eq!(name, "lift_with_speed");
            assert!(message.contains("non-finite"), "{message}");
        }
        other => panic!("{other:?}"),
    }
}

/// With a well-defined constraint declared first, the error names the one that is undefined at
/// the state (√ at 0 in the derivative of the second), not the first row checked.
#[test]
fn the_non_finite_row_names_its_own_constraint() {
    let yaml = r#"  - name: servo
    kind: velocity
    expression: "vx - 0.5"
    variables: {vx: "v:root_joint:vx_local"}
  - name: lift
    kind: velocity
    expression: "vz - 0.5*sqrt(vx^2 + vy^2)"
    variables: {vx: "v:root_joint:vx_local", vy: "v:root_joint:vy_local", vz: "v:root_joint:vz_local"}
"#;
    let mut sys = scene_from("point_mass.urdf", "floating", yaml).unwrap();
    let q = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    match sys.forward_dynamics(&q, &[0.0; 6], &[0.0; 6], true) {
        Err(Error::Constraint { name, message }) => {
            assert_eq!(name, "lift");
            assert!(message.contains("non-finite"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // Only γ undefined: f = vx − √x at x = 0 has ∂f/∂v = (1) and f = 0, but ∂f/∂x = −∞.
    let yaml = r#"  - name: root
    kind: velocity
    expression: "vx - sqrt(x)"
    variables: {vx: "v:root_joint:vx_local", x: "q:root_joint:x"}
"#;
    let mut sys = scene_from("point_mass.urdf", "floating", yaml).unwrap();
    let q = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    match sys.forward_dynamics(&q, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0], &[0.0; 6], true) {
        Err(Error::Constraint { name, message }) => {
            assert_eq!(name, "root");
            assert!(message.contains("non-finite"), "{message}");
        }
        other => panic!("{other:?}"),
    }
}

/// Long expressions parse (the parser's recursion is bounded by the nesting depth, not the
/// length), evaluate without allocating, and the length is capped with a named error.
#[test]
fn long_expressions_parse_and_overlong_ones_are_named() {
    let term = |n: usize| {
        (0..n)
            .map(|i| format!("{}*vx*vz^{}", i + 1, i % 3 + 1))
            .collect::<Vec<_>>()
            .join(" + ")
    };
    let vars = r#"{vx: "v:root_joint:vx_local", vz: "v:root_joint:vz_local"}"#;
    let decl = |e: &str| {
        format!("  - name: c\n    kind: velocity\n    expression: {e:?}\n    variables: {vars}\n")
    };
    // 45 terms = 359 tokens, under the 400 cap.
    let mut sys = scene_from("point_mass.urdf", "floating", &decl(&term(45))).unwrap();
    let q = [0.4, -1.1, 0.7, 0.0, 0.0, 0.0, 1.0];
    let v = [0.8, -0.5, 0.3, 1.2, -0.7, 0.9];
    sys.evaluate_rows(sys.rows().t, &q, &v);
    // Closed form: f = Σ (i+1) vx vz^(i%3+1), ∂f/∂vx = f/vx.
    let f: f64 = (0..45)
        .map(|i| (i + 1) as f64 * v[0] * v[2].powi(i % 3 + 1))
        .sum();
    assert_close("45-term f", &[sys.rows().jv[0]], &[f], 1e-14);
    assert_close(
        "45-term ∂f/∂vx",
        &[sys.rows().j[(0, 0)]],
        &[f / v[0]],
        1e-14,
    );
    let n = allocations(|| {
        sys.evaluate_rows(0.0, &q, &v);
    });
    assert_eq!(n, 0, "a 45-term expression's rows allocate");
    match problem(&term(60), vars, "") {
        ExpressionProblem::Syntax { message, .. } => {
            assert!(message.contains("at most 400"), "{message}")
        }
        p => panic!("{p}"),
    }
    // The cap is inclusive: 50 terms are 8·50 − 1 = 399 tokens, a leading sign makes 400
    // (accepted), `+ vx` at the end 401 (named).
    scene_from(
        "point_mass.urdf",
        "floating",
        &decl(&format!("-{}", term(50))),
    )
    .unwrap();
    match problem(&format!("{} + vx", term(50)), vars, "") {
        ExpressionProblem::Syntax { message, .. } => {
            assert_eq!(message, "401 tokens, at most 400")
        }
        p => panic!("{p}"),
    }
}

/// At most `MAX_SYMBOLS` = 16 distinct symbols (their values live in a stack buffer): 16 are
/// accepted, 17 named. Several symbols may name one coordinate: 16 symbols all naming vx give
/// f = 16 vx, so ∂f/∂vx = 16 (the derivatives of the symbols of one coordinate add up).
#[test]
fn sixteen_symbols_are_accepted_and_seventeen_named() {
    let decl = |n: usize| {
        let names: Vec<String> = (0..n).map(|i| format!("s{i}")).collect();
        let vars: Vec<String> = names
            .iter()
            .map(|s| format!("{s}: \"v:root_joint:vx_local\""))
            .collect();
        (names.join(" + "), format!("{{{}}}", vars.join(", ")))
    };
    let (e16, v16) = decl(16);
    let yaml =
        format!("  - name: c\n    kind: velocity\n    expression: {e16:?}\n    variables: {v16}\n");
    let mut sys = scene_from("point_mass.urdf", "floating", &yaml).unwrap();
    let q = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let v = [0.3, 0.0, 0.0, 0.0, 0.0, 0.0];
    sys.evaluate_rows(sys.rows().t, &q, &v);
    assert_close("f = 16 vx", &[sys.rows().jv[0]], &[16.0 * 0.3], 1e-15); // achieved 1.9e-16 (sum of 16 equal terms)
    assert_close("∂f/∂vx = 16", &[sys.rows().j[(0, 0)]], &[16.0], 1e-15); // achieved 0; floor 1e-15
    let (e17, v17) = decl(17);
    match problem(&e17, &v17, "") {
        ExpressionProblem::Syntax { message, .. } => {
            assert!(message.contains("17 symbols, at most 16"), "{message}")
        }
        p => panic!("17 symbols: {p}"),
    }
}

/// A sign before a power negates the power, `-vz^2` = −(vz²) (exmex bound the sign first,
/// (−vz)², so it was refused until the project parsed expressions itself).
#[test]
fn a_sign_before_a_power_negates_the_power() {
    let vars = r#"{vx: "v:root_joint:vx_local", vz: "v:root_joint:vz_local"}"#;
    let yaml = format!(
        "  - name: c\n    kind: velocity\n    expression: \"-vz^2 + vx\"\n    variables: {vars}\n"
    );
    let mut sys = scene_from("point_mass.urdf", "floating", &yaml).unwrap();
    let q = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let v = [0.8, -0.5, 0.3, 1.2, -0.7, 0.9];
    sys.evaluate_rows(sys.rows().t, &q, &v);
    // f = 0.8 − 0.3² = 0.71 (not 0.8 + 0.09), ∂f/∂vx = 1, ∂f/∂vz = −2·0.3.
    assert_close("f = -vz^2 + vx", &[sys.rows().jv[0]], &[0.71], 1e-15);
    let row: Vec<f64> = (0..6).map(|i| sys.rows().j[(0, i)]).collect();
    assert_close("∂f/∂v", &row, &[1.0, 0.0, -0.6, 0.0, 0.0, 0.0], 1e-15);
}

/// The expression's value and its gradient (every symbol in one sweep) allocate nothing, at
/// the longest expression accepted (400 tokens, 15 symbols).
#[test]
fn evaluation_and_gradient_do_not_allocate() {
    use constraint_dynamics::constraints::{Expression, MAX_SYMBOLS};
    let sys = scene_from(
        "point_mass.urdf",
        "floating",
        "  - name: c\n    kind: velocity\n    expression: \"vx\"\n    variables: {vx: \"v:root_joint:vx_local\"}\n",
    )
    .unwrap();
    let names: Vec<String> = (0..15).map(|i| format!("s{i}")).collect();
    let mut vars: std::collections::BTreeMap<String, String> = names
        .iter()
        .map(|s| (s.clone(), "q:root_joint:x".to_string()))
        .collect();
    vars.insert("vx".into(), "v:root_joint:vx_local".into());
    // A sign, 44 terms `sin(s0 + vx)^2` of 8 tokens joined by 43 `+`, and `+ 0*vx`: 400 tokens.
    let text = (0..44)
        .map(|i| format!("sin({} + vx)^2", names[i % 15]))
        .collect::<Vec<_>>()
        .join(" + ");
    let e = Expression::parse(sys.model(), &format!("-{text} + 0*vx"), &vars).unwrap();
    assert_eq!(e.len(), 16);
    let q = [0.4, -1.1, 0.7, 0.0, 0.0, 0.0, 1.0];
    let v = [0.8, -0.5, 0.3, 1.2, -0.7, 0.9];
    let mut vals = [0.0; MAX_SYMBOLS];
    let mut grad = [0.0; MAX_SYMBOLS];
    let (mut f, mut g) = (0.0, 0.0);
    let n = allocations(|| {
        e.values(&q, &v, 0.0, &mut vals);
        f = e.f(&vals);
        g = e.gradient(&vals, &mut grad);
    });
    assert_eq!(n, 0, "f and its gradient allocate");
    // Every s_k reads x = 0.4 and the sign negates the first term only:
    // f = (43 − 1) sin²(0.4 + 0.8), ∂f/∂vx = 42 sin(2·1.2).
    let s = 1.2f64;
    assert_close("f", &[f, g], &[42.0 * s.sin().powi(2); 2], 1e-15); // achieved 0
    let dvx = e.symbols.iter().position(|(n, _)| n == "vx").unwrap();
    assert_close("∂f/∂vx", &[grad[dvx]], &[42.0 * (2.0 * s).sin()], 1e-15); // achieved 5.0e-16
}
