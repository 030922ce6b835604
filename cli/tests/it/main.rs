//! The command-line tool's integration tests: one target, one module per command.

#[path = "../../../tests/it/common/mod.rs"]
mod common;

mod covariance_cli;
mod envelope_cli;
mod eval_cli;
mod evaluate_cli;
mod hostile_cli;
mod linearize_cli;
mod project_cli;
mod propagation_cli;
