//! `constraint_dynamics`: inspect a scene from the command line (JSON on stdout).

mod calibrate;
mod covariance;
mod envelope;
mod eval;
mod evaluate;
mod evaluate_plot;
#[cfg(test)]
mod fuzz_tests;
mod json;
mod linearize;
mod predict;
mod project;
mod report;
mod state;

use clap::{Parser, Subcommand};
use std::io::Write;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "constraint_dynamics",
    version,
    about = "Constrained rigid-body dynamics from URDF"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fit what a scene does not know (effective rolling radius and track, a heavier chassis,
    /// turning friction, process noise) to recorded drives, and write the calibrated scene.
    Calibrate(calibrate::CalibrateArgs),
    /// The base's acceleration envelope at one state: forward acceleration and deceleration,
    /// yaw acceleration left and right, each with what binds it (effort, friction, lift_off).
    Envelope(envelope::EnvelopeArgs),
    /// Constrained forward dynamics at one state: q̈, multipliers and constraint forces.
    Eval(eval::EvalArgs),
    /// How well a scene predicts a recorded drive (rosbag2 MCAP): errors per horizon against the
    /// recorded odometry (or a ground truth), and the predicted covariance's coverage.
    Evaluate(evaluate::EvaluateArgs),
    /// Linearize one integrator step: A = ∂x⁺/∂x, B = ∂x⁺/∂τ (x = (q, v), tangent space).
    Linearize(linearize::LinearizeArgs),
    /// Propagate a scene over a horizon: samples of q, v (λ with --forces), residuals, energy.
    // Boxed: its options make it several times the size of the other variants.
    Predict(Box<predict::PredictArgs>),
    /// Work-precision report of every integrator on the benchmark scenes (CSV, PNG, README).
    Report(report::ReportArgs),
    /// Velocity projection: the feasible velocity closest to a desired one, with bounds.
    Project(project::ProjectArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Calibrate(a) => calibrate::run(a),
        Command::Envelope(a) => envelope::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Evaluate(a) => evaluate::run(a),
        Command::Linearize(a) => linearize::run(a),
        Command::Predict(a) => predict::run(*a),
        Command::Report(a) => report::run(a),
        Command::Project(a) => project::run(a),
    };
    match result.and_then(|json| finite_json(&json, "output").map(|()| json)) {
        Ok(json) => {
            // Written, not println!ed: a reader that closes the pipe early (`| head`) ends
            // the output, which println! would turn into a panic.
            let text = serde_json::to_string_pretty(&json).unwrap_or_default();
            let mut out = std::io::stdout().lock();
            match writeln!(out, "{text}").and_then(|()| out.flush()) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: writing the output: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The last check before printing: serde_json prints NaN and ±∞ as `null`, and no output of
/// this tool has a `null` by design (absent values are left out), so a `null` anywhere is a
/// non-finite number that escaped the checks upstream: an error naming its path.
fn finite_json(v: &serde_json::Value, path: &str) -> constraint_dynamics::Result<()> {
    use serde_json::Value;
    match v {
        Value::Null => Err(constraint_dynamics::Error::NonFiniteOutput {
            output: path.to_string(),
            index: 0,
            value: f64::NAN,
            cause: "a result overflowed; see the input ranges in README.md".into(),
        }),
        Value::Array(a) => a
            .iter()
            .enumerate()
            .try_for_each(|(i, x)| finite_json(x, &format!("{path}[{i}]"))),
        Value::Object(o) => o
            .iter()
            .try_for_each(|(k, x)| finite_json(x, &format!("{path}.{k}"))),
        _ => Ok(()),
    }
}
