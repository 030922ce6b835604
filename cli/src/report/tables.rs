//! The README's tables: the fastest run to a given error and the digits view (per line, the
//! fastest run to 10 and 12 significant digits; every peer run).

use super::Row;
use std::fmt::Write as _;

/// "rtol 1e-10" or "dt 1.000e-4 s".
fn setting(r: &Row) -> String {
    if r.tolerance {
        format!("rtol {:.0e}", r.x)
    } else {
        format!("dt {:.3e} s", r.x)
    }
}

/// The fastest ok row with error ≤ target.
fn fastest_row<'a>(rows: impl Iterator<Item = &'a Row>, target: f64) -> Option<&'a Row> {
    rows.filter(|r| r.ok() && r.error <= target)
        .min_by(|a, b| a.cpu.total_cmp(&b.cpu))
}

/// The fastest ok row with error ≤ target, as "line (dt or rtol): time".
pub(super) fn fastest(rows: &[Row], target: f64) -> String {
    fastest_row(rows.iter(), target)
        .map(|r| format!("{} ({}): {:.3e} s", r.line, setting(r), r.cpu))
        .unwrap_or_else(|| "— (none)".into())
}

/// Significant digits of an error against the largest |q|: −log10(error / |q|max).
fn digits(error: f64, qmax: f64) -> f64 {
    -(error / qmax).log10()
}

/// The "digits" view: per line (the project's methods and each peer solver), the fastest run
/// to ≥ 10 and ≥ 12 significant digits in q; then every peer run.
pub(super) fn digits_view(rows: &[Row], qmax: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "**Digits.** The fastest run of each line to ≥ 10 and ≥ 12 significant digits in q \
         (error ≤ 1e-10·|q|max and ≤ 1e-12·|q|max, |q|max = {qmax:.4} rad; digits = \
         −log10(error / |q|max)); `—` when no run of the line gets there (its best in \
         brackets). Evaluations: right-hand sides (radau5 and the peers: + Jacobians).\n"
    );
    s.push_str("| line | ≥ 10 digits | ≥ 12 digits |\n|---|---|---|\n");
    let mut labels: Vec<&str> = rows.iter().map(|r| r.line.as_str()).collect();
    labels.dedup();
    let cell = |r: Option<&Row>, of: &[&Row]| match r {
        Some(r) => format!(
            "{}: **{:.2} ms**, {}{} evaluations, {:.1} digits",
            setting(r),
            r.cpu * 1e3,
            r.evaluations,
            r.jacobian_evaluations
                .map(|j| format!(" + {j}"))
                .unwrap_or_default(),
            digits(r.error, qmax)
        ),
        None => {
            let best = of
                .iter()
                .filter(|r| r.ok() && r.error.is_finite())
                .map(|r| digits(r.error, qmax))
                .fold(f64::NEG_INFINITY, f64::max);
            if best.is_finite() {
                format!("— (best {best:.1} digits)")
            } else {
                "— (no run)".into()
            }
        }
    };
    for l in labels {
        let of: Vec<&Row> = rows.iter().filter(|r| r.line == l).collect();
        let _ = writeln!(
            s,
            "| {l} | {} | {} |",
            cell(fastest_row(of.iter().copied(), 1e-10 * qmax), &of),
            cell(fastest_row(of.iter().copied(), 1e-12 * qmax), &of)
        );
    }
    let peers: Vec<&Row> = rows.iter().filter(|r| r.peer).collect();
    if !peers.is_empty() {
        s.push_str(
            "\nEvery peer run (error against the same reference as the fixed-step rows):\n\n\
             | peer/solver | rtol | CPU [ms] | RHS evaluations | Jacobian evaluations | steps | \
             error [rad] | digits | status |\n|---|---|---|---|---|---|---|---|---|\n",
        );
        for r in peers {
            let _ = writeln!(
                s,
                "| {} | {:.0e} | {:.3} | {} | {} | {} | {:.2e} | {:.1} | {} |",
                r.line,
                r.x,
                r.cpu * 1e3,
                r.evaluations,
                r.jacobian_evaluations
                    .map(|j| j.to_string())
                    .unwrap_or_default(),
                r.steps,
                r.error,
                digits(r.error, qmax),
                r.status.replace('|', "/")
            );
        }
    }
    s.push('\n');
    s
}
