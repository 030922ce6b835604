//! The state file: `{"q": [...], "v": [...], "tau": [...], "lagged_command": [v, ω]}` in the
//! printed coordinate order (v and tau optional, zero by default; `lagged_command`, the diff
//! drive's command lag's state [m/s, rad/s], only where the scene declares a `command_lag`, and
//! optional: without it the lag starts on the first command). Without a file, the scene's
//! initial state and τ = 0.

use constraint_dynamics::{Error, Result, Scene};
use serde::Deserialize;
use std::path::Path;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateFile {
    pub q: Vec<f64>,
    #[serde(default)]
    pub v: Option<Vec<f64>>,
    #[serde(default)]
    pub tau: Option<Vec<f64>>,
    #[serde(default)]
    pub lagged_command: Option<[f64; 2]>,
}

/// What a state file gives: (q, v, τ) and the diff drive's lagged command, where given.
pub struct Start {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub tau: Vec<f64>,
    /// (v [m/s], ω [rad/s]).
    pub lagged_command: Option<[f64; 2]>,
}

/// Load a scene, printing what the loader accepted but a user should know (a non-physical
/// inertia on a welded link, a repaired body) to stderr, one `warning:` line each.
pub fn load_scene(path: &Path) -> Result<Scene> {
    let scene = Scene::load(path)?;
    for w in &scene.model.warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// (q, v, τ) from `path`, or the scene's initial state.
pub fn load(scene: &Scene, path: Option<&Path>) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let s = load_start(scene, path)?;
    Ok((s.q, s.v, s.tau))
}

/// Everything a state file at `path` gives, or the scene's initial state.
pub fn load_start(scene: &Scene, path: Option<&Path>) -> Result<Start> {
    let nv = scene.model.nv;
    let Some(path) = path else {
        return Ok(Start {
            q: scene.q0.clone(),
            v: scene.v0.clone(),
            tau: vec![0.0; nv],
            lagged_command: None,
        });
    };
    let bad = |message: String| Error::Scene {
        file: path.display().to_string(),
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        path: path.display().to_string(),
        source: e,
    })?;
    let s: StateFile = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    let (q, v, tau) = (
        s.q,
        s.v.unwrap_or_else(|| vec![0.0; nv]),
        s.tau.unwrap_or_else(|| vec![0.0; nv]),
    );
    // Sizes, finiteness and the documented magnitudes (limits::MAX_STATE), naming the file.
    constraint_dynamics::limits::check_input_state(&scene.model, &q, &v, &tau)
        .map_err(|e| bad(e.to_string()))?;
    if let Some(lagged) = s.lagged_command {
        let lag = scene.file.actuators.diff_drive.as_ref();
        if lag.and_then(|d| d.command_lag).is_none() {
            return Err(bad(
                "lagged_command: the scene declares no actuators.diff_drive.command_lag".into(),
            ));
        }
        if !lagged.iter().all(|x| x.is_finite()) {
            return Err(bad(format!("lagged_command = {lagged:?} is not finite")));
        }
    }
    Ok(Start {
        q,
        v,
        tau,
        lagged_command: s.lagged_command,
    })
}
