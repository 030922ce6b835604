//! `predict`: propagate a scene from a state over a horizon, following commands; the trajectory as
//! JSON (samples of q, v, λ and the contacts' judgement with `--forces`, constraint residuals,
//! energies, error estimate).

use constraint_dynamics::actuators::Command;
use constraint_dynamics::predict::{DriftControl, Method, PredictionRequest, Predictor};
use constraint_dynamics::{Error, Result};
use serde::Deserialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct PredictArgs {
    /// Scene file (YAML).
    #[arg(long)]
    scene: PathBuf,
    /// State file (JSON {"q": [...], "v": [...]}, printed coordinate order); default: the scene's
    /// initial state.
    #[arg(long)]
    state: Option<PathBuf>,
    /// Commands file: JSON list of {"t": s, "base_twist": [v, ω], "joint_velocity": {joint: rate},
    /// "joint_position": {joint: position}}; each holds from its t until the next one.
    #[arg(long)]
    commands: Option<PathBuf>,
    /// Horizon [s] (default: the scene's integration.horizon).
    #[arg(long)]
    horizon: Option<f64>,
    #[arg(long, help = method_help())]
    method: Option<String>,
    /// Step [s] (fixed-step methods; first step of the adaptive methods).
    #[arg(long)]
    dt: Option<f64>,
    /// Relative tolerance of dopri5, dop853 and radau5 (default: the scene's).
    #[arg(long)]
    rtol: Option<f64>,
    /// Absolute tolerance of dopri5, dop853 and radau5 [m, rad, m/s, rad/s] (default: the scene's).
    #[arg(long)]
    atol: Option<f64>,
    /// none | baumgarte | projection (default: the scene's).
    #[arg(long)]
    drift: Option<String>,
    /// Output sample period [s] (default: the scene's).
    #[arg(long)]
    sample_period: Option<f64>,
    /// Bound on every sample's `error_estimate` [m or rad] (default: the scene's
    /// integration.max_error, 1e-3; `inf`: no check).
    #[arg(long)]
    max_error: Option<f64>,
    /// Refine dt or the tolerances and rerun when the estimate exceeds max_error.
    #[arg(long)]
    adapt: bool,
    /// Skip the error estimate's companion run (about 2× fewer evaluations); samples then have
    /// no `error_estimate` and max_error is not checked.
    #[arg(long)]
    no_error_estimate: bool,
    /// Record the multipliers λ and the constraint forces in every sample, and judge the
    /// contacts at each: `contact_check` names the first slip or lift-off and lists what it
    /// could not check (friction of a contact without `friction:`, lift-off and friction of a
    /// wheel on a planar base); nothing is assumed.
    #[arg(long)]
    forces: bool,
    /// Start covariance file ({"P": [[...]]} 2nv × 2nv, or {"sigma": {"<v_name>": σ,
    /// "<v_name>:rate": σ_v}}); every sample then carries its propagated `covariance`.
    #[arg(long)]
    covariance: Option<PathBuf>,
}

/// One entry of the commands file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CommandEntry {
    /// Start time [s].
    t: f64,
    #[serde(default)]
    base_twist: Option<[f64; 2]>,
    #[serde(default)]
    joint_velocity: BTreeMap<String, f64>,
    #[serde(default)]
    joint_position: BTreeMap<String, f64>,
}

/// `--method`'s help: every method's name.
fn method_help() -> String {
    let names = Method::names(Method::ALL.iter().copied(), " | ");
    format!("{names} (default: the scene's).")
}

/// Parse a snake_case enum name as serde would, naming the option on failure.
fn parse_enum<T: for<'de> Deserialize<'de>>(
    option: &str,
    value: &str,
    expected: &str,
) -> Result<T> {
    serde_json::from_value(Value::String(value.to_string()))
        .map_err(|_| Error::Invalid(format!("--{option} '{value}': expected one of {expected}")))
}

/// The commands-file parser, for the fuzz tests.
#[cfg(test)]
pub fn fuzz_load_commands(path: &Path) -> Result<Vec<(f64, Command)>> {
    load_commands(path)
}

fn load_commands(path: &Path) -> Result<Vec<(f64, Command)>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        path: path.display().to_string(),
        source: e,
    })?;
    let entries: Vec<CommandEntry> = serde_json::from_str(&text).map_err(|e| Error::Scene {
        file: path.display().to_string(),
        message: e.to_string(),
    })?;
    let mut out: Vec<(f64, Command)> = entries
        .into_iter()
        .map(|e| {
            (
                e.t,
                Command {
                    base_twist: e.base_twist,
                    joint_velocity: e.joint_velocity,
                    joint_position: e.joint_position,
                },
            )
        })
        .collect();
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(out)
}

pub fn run(a: PredictArgs) -> Result<Value> {
    let scene = super::state::load_scene(&a.scene)?;
    let method = match &a.method {
        Some(m) => Some(parse_enum::<Method>(
            "method",
            m,
            &Method::names(Method::ALL.iter().copied(), ", "),
        )?),
        None => None,
    };
    let drift = match &a.drift {
        Some(d) => Some(parse_enum::<DriftControl>(
            "drift",
            d,
            "none, baumgarte, projection",
        )?),
        None => None,
    };
    // The flags configure this run's predictor: the scene's `integration:` with them applied,
    // validated as a scene's would be.
    let mut p = Predictor::from_scene(&scene)?.with_settings(|s| {
        s.method = method.unwrap_or(s.method);
        s.drift = drift.unwrap_or(s.drift);
        s.dt = a.dt.unwrap_or(s.dt);
        s.rtol = a.rtol.unwrap_or(s.rtol);
        s.atol = a.atol.unwrap_or(s.atol);
        s.sample_period = a.sample_period.unwrap_or(s.sample_period);
        s.max_error = a.max_error.unwrap_or(s.max_error);
        s.adapt |= a.adapt;
        s.error_estimate &= !a.no_error_estimate;
    })?;
    let (q, v, tau) = super::state::load(&scene, a.state.as_deref())?;
    if tau.iter().any(|x| *x != 0.0) {
        return Err(Error::Invalid(
            "the state file's tau is not used by predict: give torques as forces.joint_torques \
             or actuators in the scene"
                .into(),
        ));
    }
    let commands = match &a.commands {
        Some(path) => load_commands(path)?,
        None => vec![],
    };
    let p0 = match &a.covariance {
        Some(path) => Some(super::covariance::load(p.model(), path)?),
        None => None,
    };
    let request = PredictionRequest {
        commands: &commands,
        horizon: a.horizon,
        start_covariance: p0.as_ref(),
        forces: a.forces,
        ..PredictionRequest::new(&q, &v)
    };
    let traj = p.predict(&request)?;
    let configured = p.config().settings();
    let mut out = serde_json::to_value(&traj).map_err(|e| Error::Invalid(e.to_string()))?;
    out["scene"] = Value::String(a.scene.display().to_string());
    let mut settings =
        serde_json::to_value(configured).map_err(|e| Error::Invalid(e.to_string()))?;
    // `.inf` turns these checks off; JSON has no infinity (serde_json would write null).
    for (key, x) in [
        ("max_error", configured.max_error),
        ("max_energy_error", configured.max_energy_error),
    ] {
        if x == f64::INFINITY {
            settings[key] = Value::String("inf".into());
        }
    }
    out["settings"] = settings;
    Ok(out)
}
