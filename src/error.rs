//! One error type for the library: every variant names the thing that is wrong.

use thiserror::Error;

/// Result alias used throughout the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, Error)]
pub enum Error {
    #[error("{path}: cannot read: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },

    #[error("{file}: malformed XML at line {line}, column {column}: {message}")]
    Xml {
        file: String,
        line: u32,
        column: u32,
        message: String,
    },

    #[error("{file}: {element}: {message}")]
    Urdf {
        file: String,
        element: String,
        message: String,
    },

    #[error("{file}: {message}")]
    Scene { file: String, message: String },

    #[error("unknown frame '{name}' (known frames: {known})")]
    UnknownFrame { name: String, known: String },

    #[error("unknown joint '{name}' (known joints: {known})")]
    UnknownJoint { name: String, known: String },

    #[error("{what}: expected {expected} values, got {got}")]
    Dimension {
        what: String,
        expected: usize,
        got: usize,
    },

    #[error("{what}: entry {index} is not finite ({value})")]
    NonFinite {
        what: String,
        index: usize,
        value: f64,
    },

    #[error("constraint '{name}': {message}")]
    Constraint { name: String, message: String },

    #[error("inconsistent constraints: {message}")]
    InconsistentConstraints { message: String },

    #[error("mass matrix is not positive definite: {message}")]
    SingularMass { message: String },

    #[error("integration diverged at t = {t} s: {message}")]
    Diverged { t: f64, message: String },

    #[error("step too large: {message}")]
    StepTooLarge { message: String },

    #[error("{0}")]
    Invalid(String),
}

/// Check that every entry of `x` is finite, naming `what` in the error.
pub fn check_finite(what: &str, x: &[f64]) -> Result<()> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NonFinite {
            what: what.to_string(),
            index,
            value: x[index],
        }),
        None => Ok(()),
    }
}

/// Check that `x` has `expected` entries.
pub fn check_len(what: &str, x: &[f64], expected: usize) -> Result<()> {
    if x.len() != expected {
        return Err(Error::Dimension {
            what: what.to_string(),
            expected,
            got: x.len(),
        });
    }
    Ok(())
}
