//! One error type for the library: every variant names the thing that is wrong.

use thiserror::Error;

/// Result alias used throughout the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, Error)]
/// Everything that can go wrong in the library; each variant names the offending file or item.
pub enum Error {
    /// A URDF or scene file could not be read from disk.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// Path of the file that could not be read.
        path: String,
        /// The underlying I/O error.
        source: std::io::Error,
    },

    /// The URDF text is not well-formed XML.
    #[error("{file}: malformed XML at line {line}, column {column}: {message}")]
    Xml {
        /// Name of the URDF source (path or caller-given name).
        file: String,
        /// Line of the error, 1-based.
        line: u32,
        /// Column of the error, 1-based.
        column: u32,
        /// The XML parser's message.
        message: String,
    },

    /// The URDF is valid XML but not a usable robot (bad root, unknown joint type, cycle, …).
    #[error("{file}: {element}: {message}")]
    Urdf {
        /// Name of the URDF source (path or caller-given name).
        file: String,
        /// The offending element, e.g. `joint 'knee'` or `link 'base'`.
        element: String,
        /// What is wrong with it.
        message: String,
    },

    /// A URDF number that cannot be used, located: file and line, element and attribute.
    #[error("{at}: {element}: {message}")]
    UrdfValue {
        /// `file:line` of the attribute (line 1-based).
        at: String,
        /// The element, the link or joint that holds it and the attribute as written, e.g.
        /// `<origin> of joint 'knee', xyz="0 nan 0"`.
        element: String,
        /// What is wrong with it.
        message: String,
    },

    /// The joint-space inertia matrix is singular or nearly so for every configuration the load
    /// checks: some joint moves (almost) no inertia once the joints below it are free.
    #[error("{file}: {joint}: {message}")]
    SingularModel {
        /// Name of the URDF source.
        file: String,
        /// The joint at fault, e.g. `joint 'neck_yaw'`.
        joint: String,
        /// The effective inertia found and the links it moves.
        message: String,
    },

    /// A request would do more work than its stated limit (steps, samples, evaluations).
    #[error("{what} = {estimate:.3e} exceeds the limit {limit:.3e}: {hint}")]
    WorkLimit {
        /// What is counted, e.g. `integration steps (horizon / dt)`.
        what: String,
        /// The count the request asks for (or reached).
        estimate: f64,
        /// The limit in force.
        limit: f64,
        /// Which setting raises the limit or shortens the request.
        hint: String,
    },

    /// A result came out NaN or infinite: the inputs overflow the arithmetic.
    #[error("{output} is not finite (entry {index} = {value}): {cause}")]
    NonFiniteOutput {
        /// Which output, e.g. `q̈` or `sample at t = 0.1 s: λ`.
        output: String,
        /// Index of the first non-finite entry.
        index: usize,
        /// The value found.
        value: f64,
        /// Which inputs are the likely cause.
        cause: String,
    },

    /// The scene YAML cannot be parsed or names something inconsistent with the model.
    #[error("{file}: {message}")]
    Scene {
        /// Path of the scene file.
        file: String,
        /// What is wrong with it.
        message: String,
    },

    /// A frame (link or fixed-joint frame) looked up by name does not exist in the model.
    #[error("unknown frame '{name}' (known frames: {known})")]
    UnknownFrame {
        /// The name that was asked for.
        name: String,
        /// Comma-separated list of the model's frame names.
        known: String,
    },

    /// A joint looked up by name does not exist in the model.
    #[error("unknown joint '{name}' (known joints: {known})")]
    UnknownJoint {
        /// The name that was asked for.
        name: String,
        /// Comma-separated list of the model's joint names.
        known: String,
    },

    /// A vector has the wrong number of entries (e.g. `q` not of length `nq`).
    #[error("{what}: expected {expected} values, got {got}")]
    Dimension {
        /// Which input is wrong.
        what: String,
        /// Number of entries required.
        expected: usize,
        /// Number of entries given.
        got: usize,
    },

    /// An input vector holds a NaN or an infinity.
    #[error("{what}: entry {index} is not finite ({value})")]
    NonFinite {
        /// Which input is wrong.
        what: String,
        /// Index of the first non-finite entry.
        index: usize,
        /// The offending value.
        value: f64,
    },

    /// A constraint declaration is invalid (duplicate name, unknown frame, zero axis, …).
    #[error("constraint '{name}': {message}")]
    Constraint {
        /// Name of the constraint.
        name: String,
        /// What is wrong with it.
        message: String,
    },

    /// The constraint rows are singular or their accelerations cannot all be met.
    #[error("inconsistent constraints: {message}")]
    InconsistentConstraints {
        /// Which rows or matrix failed, with the size of the violation.
        message: String,
    },

    /// The mass matrix (or reduced mass matrix `NᵀMN`) failed its Cholesky factorization.
    #[error("mass matrix is not positive definite: {message}")]
    SingularMass {
        /// Which matrix failed and at which pivot.
        message: String,
    },

    /// Integration blew up: state out of bounds, step-size underflow, energy drift or failed
    /// position projection.
    #[error("integration diverged at t = {t} s: {message}")]
    Diverged {
        /// Simulation time [s] at which divergence was detected.
        t: f64,
        /// What diverged and how to fix it.
        message: String,
    },

    /// A prediction's global error estimate of one kind of coordinate (its name ends in its unit)
    /// exceeded its bound: the answer would have fewer correct digits than asked for.
    #[error(
        "the integration error estimate of {kind} {estimate:.3e} at t = {t} s exceeds \
         {bound} = {max_error:e}: {hint}"
    )]
    ErrorEstimateExceeded {
        /// Time of the first sample over the bound [s].
        t: f64,
        /// The estimate there of the first kind over its bound [m or rad].
        estimate: f64,
        /// That kind's bound [m or rad].
        max_error: f64,
        /// The kind of coordinate, e.g. `joint_rad` (predict/error_kinds.rs).
        kind: &'static str,
        /// The setting that bounds it, e.g. `integration.max_error_joint_rad`.
        bound: &'static str,
        /// The largest estimate / bound over the kinds at that sample (> 1).
        excess: f64,
        /// A step or tolerance that would meet the bound, from the method's order.
        hint: String,
    },

    /// The time step is beyond the method's stability limit or SDIRK2's Newton iteration failed.
    #[error("step too large: {message}")]
    StepTooLarge {
        /// The limit that was exceeded and how to fix it.
        message: String,
    },

    /// An operation that has no implementation for this input yet (e.g. the derivatives of a
    /// constraint kind without analytic derivatives).
    #[error("{what} is not supported: {why}")]
    Unsupported {
        /// What was asked for.
        what: String,
        /// Why it cannot be done, and what can.
        why: String,
    },

    /// A velocity constraint's expression (`kind: velocity`) is malformed, names something
    /// unknown, or is not a velocity constraint.
    #[error("constraint '{name}': expression \"{expression}\": {problem}")]
    Expression {
        /// Name of the constraint.
        name: String,
        /// The expression as written.
        expression: String,
        /// What is wrong with it (boxed: keeps `Error` small for the callers' `Result`s).
        problem: Box<ExpressionProblem>,
    },

    /// Any other invalid argument or option; the string says what.
    #[error("{0}")]
    Invalid(String),
}

/// What is wrong with a velocity constraint's expression (see [`Error::Expression`]).
/// Columns are 1-based character positions in the expression.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum ExpressionProblem {
    /// The text does not parse.
    #[error("syntax error at column {column}: {message}")]
    Syntax {
        /// Where the error was found.
        column: usize,
        /// What was expected there.
        message: String,
    },
    /// A symbol of the expression is neither under `variables:`, nor `t`, `pi` or a function.
    #[error(
        "unknown symbol '{symbol}' at column {column} (declare it under variables:, or use t for time)"
    )]
    UnknownSymbol {
        /// The symbol.
        symbol: String,
        /// Where it appears first.
        column: usize,
    },
    /// A variable maps to a coordinate the model does not have.
    #[error("variable '{symbol}': unknown coordinate '{coordinate}' (known: {known})")]
    UnknownCoordinate {
        /// The variable.
        symbol: String,
        /// The coordinate it names (without the `q:`/`v:` prefix).
        coordinate: String,
        /// The model's coordinate names of that kind, comma-separated.
        known: String,
    },
    /// A variable's declaration is malformed (name or `q:`/`v:` prefix).
    #[error("variable '{symbol}': {message}")]
    BadVariable {
        /// The variable.
        symbol: String,
        /// What is wrong.
        message: String,
    },
    /// The expression depends on no velocity.
    #[error(
        "it does not depend on any velocity: that is a holonomic constraint f(q, t) = 0, not a \
         velocity constraint (use a position-level kind, or write its time derivative)"
    )]
    Holonomic,
    /// `dependent:` names something that is not a velocity variable, or as many velocities as
    /// the expression has.
    #[error("dependent: {message}")]
    Dependent {
        /// What is wrong.
        message: String,
    },
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

/// Check that every entry of an output `x` is finite, naming the output and the likely `cause`.
pub fn check_output(output: &str, x: &[f64], cause: &str) -> Result<()> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NonFiniteOutput {
            output: output.to_string(),
            index,
            value: x[index],
            cause: cause.to_string(),
        }),
        None => Ok(()),
    }
}
