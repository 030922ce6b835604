//! JSON shapes shared by the commands.

use nalgebra::DMatrix;
use serde_json::{Value, json};

/// Rows of a matrix as nested arrays (row-major, the printed coordinate order).
pub fn matrix_rows(m: &DMatrix<f64>) -> Value {
    json!(
        (0..m.nrows())
            .map(|i| m.row(i).iter().copied().collect::<Vec<f64>>())
            .collect::<Vec<_>>()
    )
}
