//! The command-line tool's integration tests: one target, one module per command.

#[path = "../../../tests/it/common/mod.rs"]
mod common;

mod calibrate_cli;
mod covariance_cli;
mod envelope_cli;
mod eval_cli;
mod evaluate_cli;
mod hostile_cli;
mod linearize_cli;
mod project_cli;
mod propagation_cli;

/// `constraint_dynamics ARGS` run from `dir` (the test's own directory when None): (success,
/// stdout as JSON (null when it is not), stderr).
fn run_cli(dir: Option<&std::path::Path>, args: &[&str]) -> (bool, serde_json::Value, String) {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_constraint_dynamics"));
    if let Some(d) = dir {
        cmd.current_dir(d);
    }
    let out = cmd.args(args).output().unwrap();
    (
        out.status.success(),
        serde_json::from_slice(&out.stdout).unwrap_or_default(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}
