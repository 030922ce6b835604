//! The start covariance file of `predict --covariance`: either the full matrix
//! `{"P": [[...]]}` (2nv × 2nv, order [δq; δv], tangent space, printed velocity order), or a
//! diagonal by name `{"sigma": {"<v_name>": σ_q, "<v_name>:rate": σ_v}}` (standard deviations
//! [m or rad] and [m/s or rad/s]; unnamed entries are 0).

use constraint_dynamics::{Error, Model, Result};
use nalgebra::DMatrix;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CovarianceFile {
    #[serde(rename = "P")]
    p: Option<Vec<Vec<f64>>>,
    sigma: Option<BTreeMap<String, f64>>,
}

/// The start covariance from `path` for `model`.
pub fn load(model: &Model, path: &Path) -> Result<DMatrix<f64>> {
    let file = path.display().to_string();
    let err = |message: String| Error::Scene {
        file: file.clone(),
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        path: file.clone(),
        source: e,
    })?;
    let c: CovarianceFile = serde_json::from_str(&text).map_err(|e| err(e.to_string()))?;
    let n = 2 * model.nv;
    match (c.p, c.sigma) {
        (Some(rows), None) => {
            if rows.len() != n || rows.iter().any(|r| r.len() != n) {
                return Err(err(format!("P must be {n} × {n} (2nv, order [dq; dv])")));
            }
            Ok(DMatrix::from_fn(n, n, |i, j| rows[i][j]))
        }
        (None, Some(sigma)) => {
            let mut p = DMatrix::zeros(n, n);
            for (name, &s) in &sigma {
                if !((s * s).is_finite() && s >= 0.0) {
                    return Err(err(format!(
                        "sigma.{name} = {s}: must be ≥ 0 with a finite square"
                    )));
                }
                let (base, off) = match name.strip_suffix(":rate") {
                    Some(b) => (b, model.nv),
                    None => (name.as_str(), 0),
                };
                let i = model.v_index(base)?;
                p[(off + i, off + i)] = s * s;
            }
            Ok(p)
        }
        _ => Err(err("give exactly one of \"P\" or \"sigma\"".into())),
    }
}
