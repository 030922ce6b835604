//! `constraint_dynamics`: inspect a scene from the command line (JSON on stdout).

mod covariance;
mod eval;
mod linearize;
mod predict;
mod project;
mod report;
mod state;

use clap::{Parser, Subcommand};
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
    /// Constrained forward dynamics at one state: q̈, multipliers and constraint forces.
    Eval(eval::EvalArgs),
    /// Linearize one integrator step: A = ∂x⁺/∂x, B = ∂x⁺/∂τ (x = (q, v), tangent space).
    Linearize(linearize::LinearizeArgs),
    /// Propagate a scene over a horizon: samples of q, v (λ with --forces), residuals, energy.
    Predict(predict::PredictArgs),
    /// Work-precision report of every integrator on the benchmark scenes (CSV, PNG, README).
    Report(report::ReportArgs),
    /// Velocity projection: the feasible velocity closest to a desired one, with bounds.
    Project(project::ProjectArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Eval(a) => eval::run(a),
        Command::Linearize(a) => linearize::run(a),
        Command::Predict(a) => predict::run(a),
        Command::Report(a) => report::run(a),
        Command::Project(a) => project::run(a),
    };
    match result {
        Ok(json) => {
            println!(
                "{}",
                serde_json::to_string_pretty(&json).unwrap_or_default()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
