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
    /// State file (JSON {"q": [...], "v": [...]}, printed coordinate order, and where the scene
    /// declares a command lag its state "lagged_command": [v, ω]); default: the scene's initial
    /// state.
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
    /// Bound on every sample's error estimate, every kind of coordinate in its own unit [m or
    /// rad] (default: the scene's integration.max_error, 1e-3, and its per-kind keys, which
    /// this replaces; `inf`: no check).
    #[arg(long)]
    max_error: Option<f64>,
    /// Bound on the estimate of the base's position [m] (default: the scene's
    /// integration.max_error_base_m, else max_error).
    #[arg(long)]
    max_error_base_m: Option<f64>,
    /// Bound on the estimate of the base's orientation [rad] (default: the scene's
    /// integration.max_error_base_rad, else max_error).
    #[arg(long)]
    max_error_base_rad: Option<f64>,
    /// Bound on the estimate of the revolute joints' angles, wheels included [rad] (default:
    /// the scene's integration.max_error_joint_rad, else max_error).
    #[arg(long)]
    max_error_joint_rad: Option<f64>,
    /// Bound on the estimate of the prismatic joints' displacements [m] (default: the scene's
    /// integration.max_error_joint_m, else max_error).
    #[arg(long)]
    max_error_joint_m: Option<f64>,
    /// Hold every position-controlled joint at its start position wherever the commands do not
    /// set it (from t = 0, also without a commands file), as the predictor node does
    /// (`command.hold_joints`); without it such a joint's controller has no target and the
    /// joint moves freely.
    #[arg(long)]
    hold_joints: bool,
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
        if let Some(x) = a.max_error {
            s.set_max_error(x);
        }
        s.max_error_base_m = a.max_error_base_m.or(s.max_error_base_m);
        s.max_error_base_rad = a.max_error_base_rad.or(s.max_error_base_rad);
        s.max_error_joint_rad = a.max_error_joint_rad.or(s.max_error_joint_rad);
        s.max_error_joint_m = a.max_error_joint_m.or(s.max_error_joint_m);
        s.adapt |= a.adapt;
        s.error_estimate &= !a.no_error_estimate;
    })?;
    let start = super::state::load_start(&scene, a.state.as_deref())?;
    let (q, v) = (start.q, start.v);
    if start.tau.iter().any(|x| *x != 0.0) {
        return Err(Error::Invalid(
            "the state file's tau is not used by predict: give torques as forces.joint_torques \
             or actuators in the scene"
                .into(),
        ));
    }
    let mut commands = match &a.commands {
        Some(path) => load_commands(path)?,
        None => vec![],
    };
    if a.hold_joints {
        hold_joints(&scene, p.model(), &q, &mut commands)?;
    }
    let p0 = match &a.covariance {
        Some(path) => Some(super::covariance::load(p.model(), path)?),
        None => None,
    };
    let request = PredictionRequest {
        commands: &commands,
        horizon: a.horizon,
        start_covariance: p0.as_ref(),
        forces: a.forces,
        lagged_command: start.lagged_command,
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
        ("max_error", Some(configured.max_error)),
        ("max_energy_error", Some(configured.max_energy_error)),
        ("max_error_base_m", configured.max_error_base_m),
        ("max_error_base_rad", configured.max_error_base_rad),
        ("max_error_joint_rad", configured.max_error_joint_rad),
        ("max_error_joint_m", configured.max_error_joint_m),
    ] {
        let Some(x) = x else { continue };
        if x == f64::INFINITY {
            settings[key] = Value::String("inf".into());
        }
    }
    out["settings"] = settings;
    Ok(out)
}

/// `--hold-joints`: every command (one at t = 0 when none starts there) targets each
/// position-controlled joint it does not set at its start position `q`.
fn hold_joints(
    scene: &constraint_dynamics::Scene,
    model: &constraint_dynamics::model::Model,
    q: &[f64],
    commands: &mut Vec<(f64, Command)>,
) -> Result<()> {
    if commands.first().is_none_or(|(t, _)| *t > 0.0) {
        commands.insert(0, (0.0, Command::default()));
    }
    for spec in &scene.file.actuators.position {
        let b = model.joint_body(&spec.joint)?;
        let at = q[model.bodies[b].joint.idx_q];
        for (_, c) in commands.iter_mut() {
            c.joint_position.entry(spec.joint.clone()).or_insert(at);
        }
    }
    Ok(())
}
