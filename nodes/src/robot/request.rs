//! State vectors from a request's fields: positional, or by coordinate name on top of the
//! latest state; every value checked finite, every name known.

use crate::error::NodeError;

/// A state vector from a request: positional (`names` empty: all `known.len()` values, or none
/// for `v` when `empty_is_zero`), or by name on top of `latest`.
pub fn assemble(
    what: &str,
    names: &[String],
    values: &[f64],
    latest: &[f64],
    known: &[String],
    empty_is_zero: bool,
) -> Result<Vec<f64>, NodeError> {
    let n = known.len();
    if names.is_empty() {
        if values.is_empty() && empty_is_zero {
            return Ok(vec![0.0; n]);
        }
        check_values(what, values, known)?;
        return Ok(values.to_vec());
    }
    same_len(&format!("{what}_names"), names, what, values.len())?;
    let mut out = latest.to_vec();
    for (name, x) in names.iter().zip(values) {
        let i = known.iter().position(|k| k == name).ok_or_else(|| {
            NodeError::request(
                format!("{what}_names"),
                format!("unknown coordinate '{name}' (known: {})", known.join(", ")),
            )
        })?;
        if !x.is_finite() {
            return Err(NodeError::request(
                what,
                format!("value of '{name}' is not finite ({x})"),
            ));
        }
        out[i] = *x;
    }
    Ok(out)
}

/// One finite value per name, naming the coordinate that is not.
pub fn check_values(what: &str, values: &[f64], names: &[String]) -> Result<(), NodeError> {
    if values.len() != names.len() {
        return Err(NodeError::request(
            what,
            format!(
                "expected {} values ({}), got {}",
                names.len(),
                names.join(", "),
                values.len()
            ),
        ));
    }
    match values.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(NodeError::request(
            what,
            format!(
                "value of '{}' (entry {i}) is not finite ({})",
                names[i], values[i]
            ),
        )),
        None => Ok(()),
    }
}

/// `names` and the field `b` (of length `n`) have the same length.
pub fn same_len(a: &str, names: &[String], b: &str, n: usize) -> Result<(), NodeError> {
    if names.len() == n {
        Ok(())
    } else {
        Err(NodeError::LengthMismatch {
            names: a.to_string(),
            n_names: names.len(),
            values: b.to_string(),
            n_values: n,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(xs: &[&str]) -> Vec<String> {
        xs.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn positional_named_and_refused() {
        let known = names(&["a", "b"]);
        let latest = [1.0, 2.0];
        assert_eq!(
            assemble("v", &[], &[], &latest, &known, true).unwrap(),
            [0.0, 0.0]
        );
        assert_eq!(
            assemble("q", &[], &[3.0, 4.0], &latest, &known, false).unwrap(),
            [3.0, 4.0]
        );
        let e = assemble("q", &[], &[], &latest, &known, false)
            .unwrap_err()
            .to_string();
        assert_eq!(e, "q: expected 2 values (a, b), got 0");
        let by_name = assemble("q", &names(&["b"]), &[5.0], &latest, &known, false).unwrap();
        assert_eq!(by_name, [1.0, 5.0]);
        let e = assemble("q", &names(&["c"]), &[5.0], &latest, &known, false).unwrap_err();
        assert!(
            e.to_string().contains("q_names: unknown coordinate 'c'"),
            "{e}"
        );
        let e = assemble("v", &[], &[f64::NAN, 0.0], &latest, &known, true).unwrap_err();
        assert!(
            e.to_string()
                .contains("value of 'a' (entry 0) is not finite"),
            "{e}"
        );
        let e = same_len("bound_names", &known, "lower", 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("bound_names has 2 entries but lower has 1"),
            "{e}"
        );
    }
}
